//! Procedures: anatomy, models, tools and task steps composed from a scenario, and the
//! registry that lists them for the command line, the window and the recordings.

pub mod nephrectomy;

pub use nephrectomy::Nephrectomy;

/// What the rest of the program knows of a procedure before it runs.
#[derive(Debug)]
pub struct ProcedureInfo {
    /// The name used on the command line, in scenarios, traces and recordings.
    pub name: &'static str,
    /// A title for people.
    pub title: &'static str,
    /// The paper it follows (file under `shared/papers/`).
    pub paper: &'static str,
    /// The default scenario (TOML text).
    pub scenario: &'static str,
    /// The demo trace `vesalius demo`, `bench` and `profile` play (TOML text).
    pub demo_trace: &'static str,
}

/// Every procedure that runs today, in the order `vesalius demo` plays them.
pub const REGISTRY: &[&ProcedureInfo] = &[&nephrectomy::INFO];

/// The registered procedure called `name`.
pub fn find(name: &str) -> Option<&'static ProcedureInfo> {
    REGISTRY.iter().copied().find(|p| p.name == name)
}

/// The registered procedures' names.
pub fn names() -> impl Iterator<Item = &'static str> {
    REGISTRY.iter().map(|p| p.name)
}
