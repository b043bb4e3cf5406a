//! The simulated runtime's settings: a TOML file named by `VESALIUS_XR_SIM_CONFIG` (none: the
//! defaults). Bad settings make instance creation fail with `XR_ERROR_RUNTIME_FAILURE` and a
//! message on stderr naming the file and key.

use serde::Deserialize;
use std::path::PathBuf;

/// The environment variable naming the settings file.
pub const CONFIG_ENV: &str = "VESALIUS_XR_SIM_CONFIG";
/// The haptics log's name in the output folder.
pub const HAPTICS_FILE: &str = "haptics.jsonl";

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Where the runtime writes its outputs (`session-states.log`, `haptics.jsonl`,
    /// `frames/`); none: nothing is written.
    pub out_dir: Option<PathBuf>,
    /// A keyframed trace (`assets/traces/` format) that moves the head and controllers and
    /// presses the buttons; relative paths are from the settings file's folder. None: the head
    /// stands still and no controller is there.
    pub trace: Option<PathBuf>,
    /// Dump the submitted eye images of every Nth frame into `frames/` (0: none). Default 30
    /// (three images a second at 90 Hz).
    #[serde(default = "default_every")]
    pub frames_every: u32,
    #[serde(default)]
    pub inject: Inject,
}

fn default_every() -> u32 {
    30
}

impl Default for Config {
    fn default() -> Self {
        Config {
            out_dir: None,
            trace: None,
            frames_every: default_every(),
            inject: Inject::default(),
        }
    }
}

/// A hand, as the settings name it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HandName {
    Left,
    Right,
}

impl HandName {
    pub fn index(self) -> usize {
        match self {
            HandName::Left => 0,
            HandName::Right => 1,
        }
    }
}

/// A controller out of tracking (battery out, out of the base stations' view) for a while.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerLoss {
    pub hand: HandName,
    /// From this time, seconds after the first frame...
    pub from_s: f64,
    /// ...until this time, seconds.
    pub to_s: f64,
}

/// Faults to inject, at display times counted from the first frame.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Inject {
    /// The session is lost (LOSS_PENDING) at this time, seconds; none: never.
    pub session_loss_s: Option<f64>,
    /// After a loss, how many `xrGetSystem` calls find no headset before it is back.
    #[serde(default = "default_back")]
    pub headset_back_after_polls: u32,
    /// Controllers lost for a while: `[[inject.controller_loss]]` with `hand`, `from_s`,
    /// `to_s`.
    #[serde(default)]
    pub controller_loss: Vec<ControllerLoss>,
}

fn default_back() -> u32 {
    3
}

impl Default for Inject {
    fn default() -> Self {
        Inject {
            session_loss_s: None,
            headset_back_after_polls: default_back(),
            controller_loss: Vec::new(),
        }
    }
}

/// What is wrong with the settings, or with a file or folder they name.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The settings file named by [`CONFIG_ENV`] cannot be read.
    #[error("{} (from {CONFIG_ENV}): {source}", file.display())]
    Read {
        file: PathBuf,
        source: std::io::Error,
    },
    /// Not TOML, or a key that is not a setting, or a value of the wrong type.
    #[error("{file}: {source}")]
    Toml {
        file: String,
        source: toml::de::Error,
    },
    #[error(
        "{file}: inject.controller_loss[{index}]: expected 0 <= from_s < to_s, in seconds, got {from_s} and {to_s}"
    )]
    ControllerLoss {
        file: String,
        index: usize,
        from_s: f64,
        to_s: f64,
    },
    #[error(
        "{file}: inject.session_loss_s: expected a time in seconds greater than 0, got {value}"
    )]
    SessionLoss { file: String, value: f64 },
    /// The trace the settings name cannot be read.
    #[error("{}: cannot read the trace: {source}", path.display())]
    ReadTrace {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The trace the settings name is not a valid keyframed trace: the key and why.
    #[error("{}: {key}: {message}", path.display())]
    Trace {
        path: PathBuf,
        key: String,
        message: String,
    },
    /// The output folder (or a log in it) cannot be made.
    #[error("{}: {source}", dir.display())]
    Outputs {
        dir: PathBuf,
        source: std::io::Error,
    },
}

impl Config {
    /// Parses and checks settings; `file` names them in errors.
    pub fn parse(file: &str, text: &str) -> Result<Config, ConfigError> {
        let mut c: Config = toml::from_str(text).map_err(|source| ConfigError::Toml {
            file: file.to_string(),
            source,
        })?;
        for (index, l) in c.inject.controller_loss.iter().enumerate() {
            if !(l.from_s.is_finite() && l.to_s.is_finite() && 0.0 <= l.from_s && l.from_s < l.to_s)
            {
                return Err(ConfigError::ControllerLoss {
                    file: file.to_string(),
                    index,
                    from_s: l.from_s,
                    to_s: l.to_s,
                });
            }
        }
        if let Some(t) = c.trace.as_mut()
            && t.is_relative()
            && let Some(dir) = std::path::Path::new(file).parent()
        {
            *t = dir.join(&*t);
        }
        if let Some(t) = c.inject.session_loss_s
            && !(t.is_finite() && t > 0.0)
        {
            return Err(ConfigError::SessionLoss {
                file: file.to_string(),
                value: t,
            });
        }
        Ok(c)
    }

    /// The trace the settings name, read and checked.
    pub fn load_trace(&self) -> Result<Option<xr_bindings::keyframes::KeyframeFile>, ConfigError> {
        let Some(path) = self.trace.as_ref() else {
            return Ok(None);
        };
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::ReadTrace {
            path: path.clone(),
            source,
        })?;
        xr_bindings::keyframes::KeyframeFile::parse(&text)
            .map(Some)
            .map_err(|e| ConfigError::Trace {
                path: path.clone(),
                key: e.key,
                message: e.message,
            })
    }

    /// Makes the output folder and empties the logs a run appends to.
    pub fn start_outputs(&self) -> Result<(), ConfigError> {
        let Some(dir) = self.out_dir.as_ref() else {
            return Ok(());
        };
        let fail = |source: std::io::Error| ConfigError::Outputs {
            dir: dir.clone(),
            source,
        };
        std::fs::create_dir_all(dir.join("frames")).map_err(fail)?;
        std::fs::write(dir.join(HAPTICS_FILE), "").map_err(fail)?;
        Ok(())
    }

    /// The settings named by [`CONFIG_ENV`], or the defaults when it is not set.
    pub fn from_env() -> Result<Config, ConfigError> {
        let Some(path) = std::env::var_os(CONFIG_ENV) else {
            return Ok(Config::default());
        };
        let file = PathBuf::from(path);
        let text = std::fs::read_to_string(&file).map_err(|source| ConfigError::Read {
            file: file.clone(),
            source,
        })?;
        Config::parse(&file.display().to_string(), &text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_parse_with_defaults_and_bad_ones_name_the_key() {
        let c = Config::parse(
            "a.toml",
            "out_dir = \"/tmp/x\"\n[inject]\nsession_loss_s = 0.5\n",
        )
        .expect("valid");
        assert_eq!(c.inject.session_loss_s, Some(0.5));
        assert_eq!(c.inject.headset_back_after_polls, 3);
        assert_eq!(
            Config::parse("a.toml", "").expect("empty"),
            Config::default()
        );
        let text = |s: &str| match Config::parse("a.toml", s) {
            Ok(c) => panic!("accepted: {c:?}"),
            Err(e) => e.to_string(),
        };
        let e = text("[inject]\nsession_loss_s = -1.0\n");
        assert!(e.starts_with("a.toml: inject.session_loss_s"), "{e}");
        let e = text("[inject]\nsession_loss_s = nan\n");
        assert!(e.contains("session_loss_s"), "{e}");
        let e = text("outdir = \"x\"\n");
        assert!(e.contains("a.toml") && e.contains("outdir"), "{e}");
        let e = text(
            "[inject]\n[[inject.controller_loss]]\nhand = \"left\"\nfrom_s = 2.0\nto_s = 1.0\n",
        );
        assert_eq!(
            e,
            "a.toml: inject.controller_loss[0]: expected 0 <= from_s < to_s, in seconds, got 2 and 1"
        );
        let missing = Config {
            trace: Some(PathBuf::from("/no/such/trace.toml")),
            ..Config::default()
        };
        let e = missing.load_trace().expect_err("no trace file").to_string();
        assert!(
            e.starts_with("/no/such/trace.toml: cannot read the trace: "),
            "{e}"
        );
    }
}
