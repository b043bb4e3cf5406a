//! The simulated runtime's settings: a TOML file named by `VESALIUS_XR_SIM_CONFIG` (none: the
//! defaults). Bad settings make instance creation fail with `XR_ERROR_RUNTIME_FAILURE` and a
//! message on stderr naming the file and key.

use serde::Deserialize;
use std::path::PathBuf;

/// The environment variable naming the settings file.
pub const CONFIG_ENV: &str = "VESALIUS_XR_SIM_CONFIG";

#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Where the runtime writes its outputs (`session-states.log`); none: nothing is written.
    pub out_dir: Option<PathBuf>,
    #[serde(default)]
    pub inject: Inject,
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
}

fn default_back() -> u32 {
    3
}

impl Default for Inject {
    fn default() -> Self {
        Inject {
            session_loss_s: None,
            headset_back_after_polls: default_back(),
        }
    }
}

impl Config {
    /// Parses and checks settings; `file` names them in errors.
    pub fn parse(file: &str, text: &str) -> Result<Config, String> {
        let c: Config = toml::from_str(text).map_err(|e| format!("{file}: {e}"))?;
        if let Some(t) = c.inject.session_loss_s
            && !(t.is_finite() && t > 0.0)
        {
            return Err(format!(
                "{file}: inject.session_loss_s: expected a time in seconds greater than 0, got {t}"
            ));
        }
        Ok(c)
    }

    /// The settings named by [`CONFIG_ENV`], or the defaults when it is not set.
    pub fn from_env() -> Result<Config, String> {
        let Some(path) = std::env::var_os(CONFIG_ENV) else {
            return Ok(Config::default());
        };
        let file = PathBuf::from(path);
        let text = std::fs::read_to_string(&file)
            .map_err(|e| format!("{} (from {CONFIG_ENV}): {e}", file.display()))?;
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
        let e = Config::parse("a.toml", "[inject]\nsession_loss_s = -1.0\n").unwrap_err();
        assert!(e.starts_with("a.toml: inject.session_loss_s"), "{e}");
        let e = Config::parse("a.toml", "[inject]\nsession_loss_s = nan\n").unwrap_err();
        assert!(e.contains("session_loss_s"), "{e}");
        let e = Config::parse("a.toml", "outdir = \"x\"\n").unwrap_err();
        assert!(e.contains("a.toml") && e.contains("outdir"), "{e}");
    }
}
