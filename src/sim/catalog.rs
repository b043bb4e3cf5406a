//! The procedures a program knows, handed down by the registry at the top: lower layers that
//! must resolve a procedure by name (a scenario's `procedure` key, an assessment tree's, the
//! parameter docs) take a `&Catalog` instead of naming the registry.

use super::{BuildError, Plan, Procedure, ProcedureInfo};
use crate::scenario::InputError;

/// A list of procedures, in the order `vesalius demo` plays them.
#[derive(Debug, Clone, Copy)]
pub struct Catalog(pub &'static [&'static ProcedureInfo]);

impl Catalog {
    /// Every procedure, in order.
    pub fn iter(&self) -> impl Iterator<Item = &'static ProcedureInfo> + use<> {
        self.0.iter().copied()
    }

    /// The procedure called `name`.
    pub fn find(&self, name: &str) -> Option<&'static ProcedureInfo> {
        self.iter().find(|p| p.name == name)
    }

    /// The procedures' names, in order.
    pub fn names(&self) -> impl Iterator<Item = &'static str> + use<> {
        self.iter().map(|p| p.name)
    }

    /// The procedure called `name`, or an error naming `file` and `key` that lists the ones
    /// there are.
    pub fn lookup(
        &self,
        file: &str,
        key: &str,
        name: &str,
    ) -> Result<&'static ProcedureInfo, InputError> {
        self.find(name).ok_or_else(|| {
            InputError::new(
                file,
                key,
                format!(
                    "unknown procedure '{name}', expected one of {}",
                    self.names().collect::<Vec<_>>().join(", ")
                ),
            )
        })
    }

    /// Plans the session a scenario describes (its `procedure` key picks who reads it).
    pub fn plan(
        &self,
        file: &str,
        text: &str,
    ) -> Result<(&'static ProcedureInfo, Plan), InputError> {
        let info = self.lookup(
            file,
            "procedure",
            &crate::scenario::procedure_of(file, text)?,
        )?;
        Ok((info, (info.plan)(file, text)?))
    }

    /// Builds the procedure a scenario names (its `procedure` key).
    pub fn build(&self, file: &str, text: &str) -> Result<Box<dyn Procedure>, BuildError> {
        let info = self.lookup(
            file,
            "procedure",
            &crate::scenario::procedure_of(file, text)?,
        )?;
        (info.build)(file, text)
    }
}
