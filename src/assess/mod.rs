//! Assessment shared by every procedure: alarms for the supervising surgeon, and the
//! scoring of a session by a tree of metrics read from data (`assets/assessment/*.toml`)
//! with fuzzy levels of expertise. Each procedure measures its own task (see its folder
//! under `procedures/`); the tree says how the measures are weighed.

pub mod alarms;
pub mod calibrate;
pub mod fuzzy;
pub mod html;
pub mod motion;
pub mod rules;
pub mod stats;
pub mod tree;
pub mod validation;

pub use tree::{Assessment, Tree};

use crate::scenario::InputError;
use crate::sim::{Catalog, ProcedureInfo};

/// That `tree` is `info`'s and binds only measures it reports (`file` names it in errors).
pub fn check_for(info: &ProcedureInfo, file: &str, tree: &Tree) -> Result<(), InputError> {
    if tree.procedure != info.name {
        return Err(InputError::new(
            file,
            "procedure",
            format!(
                "the tree is for '{}', the session is a '{}'",
                tree.procedure, info.name
            ),
        ));
    }
    let mut names: Vec<String> =
        tree::measures(&(info.blank_metrics)(), false, 0, 0, info.steps.len(), 0.0)
            .into_keys()
            .collect();
    names.extend(
        motion::Motion::default()
            .measures()
            .into_iter()
            .map(|(k, _)| k),
    );
    tree.check_measures(file, &names)
}

/// Reads a tree file's text and checks it against the procedure of `catalog` it names.
pub fn load(catalog: &Catalog, file: &str, text: &str) -> Result<Tree, InputError> {
    let tree = Tree::parse(file, text)?;
    let info = catalog.find(&tree.procedure).ok_or_else(|| {
        InputError::new(
            file,
            "procedure",
            format!(
                "'{}' is not a registered procedure ({})",
                tree.procedure,
                catalog.names().collect::<Vec<_>>().join(", ")
            ),
        )
    })?;
    check_for(info, file, &tree)?;
    Ok(tree)
}

/// Reads and checks a tree file against the procedures of `catalog`.
pub fn load_file(catalog: &Catalog, path: &std::path::Path) -> Result<Tree, InputError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path)
        .map_err(|e| InputError::new(&file, "file", format!("cannot read: {e}")))?;
    load(catalog, &file, &text)
}

#[cfg(test)]
mod tree_tests;

pub mod questionnaire;
#[cfg(test)]
mod questionnaire_tests;
