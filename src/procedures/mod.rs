//! Procedures: anatomy, models, tools and task steps composed from a scenario, and the
//! registry that lists them for the command line, the window and the recordings. A new
//! procedure is a folder here and one line in [`REGISTRY`].

use crate::scenario::InputError;

pub mod catheter;
pub mod cholecystectomy;
pub mod myotomy;
pub mod nephrectomy;
pub mod precompute;
mod procedure;
pub mod rectum;
pub mod sandbox;
pub mod scope;
pub mod soft_tissue;

pub use nephrectomy::Nephrectomy;
pub use procedure::{
    BuildError, MassSpring, ModelReport, Plan, Procedure, ProcedureInfo, ProcedureReport,
    TaskStatus, TaskStep, ToolInfo, ToolKind, Tunable, Viewpoint, out_of_order, tick_off,
};

/// Every procedure that runs today, in the order `vesalius demo` plays them.
pub const REGISTRY: &[&ProcedureInfo] = &[
    &nephrectomy::INFO,
    &sandbox::INFO,
    &rectum::INFO,
    &cholecystectomy::INFO,
    &myotomy::INFO,
    &catheter::INFO,
];

/// The registered procedure called `name`.
pub fn find(name: &str) -> Option<&'static ProcedureInfo> {
    REGISTRY.iter().copied().find(|p| p.name == name)
}

/// The registered procedures' names.
pub fn names() -> impl Iterator<Item = &'static str> {
    REGISTRY.iter().map(|p| p.name)
}

/// The registered procedure called `name`, or an error naming `file` and `key` that lists
/// the registered ones.
pub fn lookup(file: &str, key: &str, name: &str) -> Result<&'static ProcedureInfo, InputError> {
    crate::scenario::check_procedure(file, key, name)?;
    find(name).ok_or_else(|| InputError::new(file, key, format!("unknown procedure '{name}'")))
}

/// Builds the procedure a scenario names (its `procedure` key).
pub fn build(file: &str, text: &str) -> Result<Box<dyn Procedure>, BuildError> {
    let info = lookup(
        file,
        "procedure",
        &crate::scenario::procedure_of(file, text)?,
    )?;
    (info.build)(file, text)
}

/// Plans the session a scenario describes (its `procedure` key picks who reads it).
pub fn plan(file: &str, text: &str) -> Result<(&'static ProcedureInfo, Plan), InputError> {
    let info = lookup(
        file,
        "procedure",
        &crate::scenario::procedure_of(file, text)?,
    )?;
    Ok((info, (info.plan)(file, text)?))
}
