//! The one error every input file gives: which file, which key or line, what was expected.
//! A leaf: scenarios, parameters, traces and trees all report through it.

/// An input-file problem, for people: which file, which key or line, what was expected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {key}: {message}")]
pub struct InputError {
    pub file: String,
    pub key: String,
    pub message: String,
}

impl InputError {
    pub fn new(file: &str, key: &str, message: impl Into<String>) -> Self {
        Self {
            file: file.to_string(),
            key: key.to_string(),
            message: message.into(),
        }
    }

    /// Nothing where a rule between a file's values `holds`; else the error at `key` with the
    /// `message` (built only then).
    pub fn require(
        holds: bool,
        file: &str,
        key: &str,
        message: impl FnOnce() -> String,
    ) -> Result<(), Self> {
        if holds {
            Ok(())
        } else {
            Err(Self::new(file, key, message()))
        }
    }

    /// Wraps a TOML error, keeping its line and column.
    pub fn toml(file: &str, e: &toml::de::Error) -> Self {
        let key = match e.span() {
            Some(_) => "toml".to_string(),
            None => "file".to_string(),
        };
        Self::new(file, &key, e.to_string().trim_end().replace('\n', " | "))
    }
}
