//! The registry: every procedure this program runs, in the order `vesalius demo` plays them.
//! It is data at the top of the program: the command line, the window, the headset, the
//! session and the tests read it; nothing below `procedures/` names it, and lower layers that
//! must resolve a procedure by name are handed [`CATALOG`].
//!
//! Adding a procedure is a folder under `src/procedures/`, its assets (scenario, demo trace,
//! assessment tree) and one line here.

use crate::procedures::{catheter, cholecystectomy, myotomy, nephrectomy, rectum, sandbox};
use crate::sim::{Catalog, ProcedureInfo};

/// Every procedure that runs today, in the order `vesalius demo` plays them.
pub const REGISTRY: &[&ProcedureInfo] = &[
    &nephrectomy::INFO,
    &sandbox::INFO,
    &rectum::INFO,
    &cholecystectomy::INFO,
    &myotomy::INFO,
    &catheter::INFO,
];

/// The registry as the core's catalog, for the layers below that resolve names.
pub const CATALOG: Catalog = Catalog(REGISTRY);

/// The registered procedure called `name`.
pub fn find(name: &str) -> Option<&'static ProcedureInfo> {
    CATALOG.find(name)
}

/// The registered procedures' names.
pub fn names() -> impl Iterator<Item = &'static str> {
    CATALOG.names()
}

/// Plans the session a scenario describes (its `procedure` key picks who reads it).
pub fn plan(
    file: &str,
    text: &str,
) -> Result<(&'static ProcedureInfo, crate::sim::Plan), crate::scenario::InputError> {
    CATALOG.plan(file, text)
}

/// Builds the procedure a scenario names (its `procedure` key).
pub fn build(
    file: &str,
    text: &str,
) -> Result<Box<dyn crate::sim::Procedure>, crate::sim::BuildError> {
    CATALOG.build(file, text)
}

/// The built-in scenario of the registered procedure called `name` (TOML text).
pub fn builtin(name: &str) -> Option<&'static str> {
    find(name).map(|p| p.scenario)
}

/// `docs/parameters.md`: the parameter tables of every procedure of `catalog` (the
/// registry's [`CATALOG`] for the shipped file).
pub fn document(catalog: &Catalog) -> String {
    let mut out = String::from(
        "# Scenario parameters\n\nGenerated from the parameter tables in the code (`ParamSpec`); \
         a test fails when this file is stale (`VESALIUS_BLESS=1 cargo test --lib registry` \
         rewrites it). Every number a scenario holds is here, with its unit, its one default \
         and the range a scenario may give (inclusive); an error names the file and \
         `table.key`. Each scenario gives every value. The shipped scenarios \
         (`assets/scenarios/`) hold the defaults, a test checks, except in the soft-body \
         tables: one table serves several models, each with its own values, and its default \
         is what the model's `Default` holds. An array's elements are listed as `key[0]`, \
         `key[1]`, ...; a whole number is a count. A slider is shown in the desktop window for \
         the values the procedure lets the supervisor tune, and its changes are recorded with \
         the session. Checks that tie values together (a direction's length, the points a \
         resolution asks for, a sum of weights, a depth within the block) are made by each \
         procedure's code after these ranges.\n",
    );
    for p in catalog.iter() {
        out += &format!("\n## {} (`{}`)\n", p.title, p.name);
        for (table, specs) in p.param_tables {
            out += &format!(
                "\n### {}\n\n{}",
                crate::params::heading(table),
                crate::params::markdown(specs)
            );
        }
    }
    out
}

#[cfg(test)]
#[path = "registry_tests.rs"]
mod tests;
