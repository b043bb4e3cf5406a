//! Procedures: anatomy, models, tools and task steps composed from a scenario.

pub mod nephrectomy;

pub use nephrectomy::Nephrectomy;
