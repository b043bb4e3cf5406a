//! Procedures: anatomy, models, tools and task steps composed from a scenario. Each folder is
//! one procedure, a plug-in of the core's `Procedure` trait; the registry at the top
//! ([`crate::registry`]) lists them. Nothing below this folder names one.

pub mod catheter;
pub mod cholecystectomy;
pub mod myotomy;
pub mod nephrectomy;
pub mod rectum;
pub mod sandbox;
pub mod scope;
pub mod soft_tissue;

pub use crate::sim::{
    BuildError, MassSpring, ModelReport, Plan, Procedure, ProcedureInfo, ProcedureReport,
    TaskStatus, TaskStep, ToolInfo, ToolKind, Tunable, Viewpoint, out_of_order, tick_off,
};
pub use nephrectomy::Nephrectomy;
