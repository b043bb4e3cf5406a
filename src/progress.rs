//! A progress bar on standard error for long precomputations: redrawn in place on a
//! terminal, a line every 10 % otherwise (logs, CI).

use std::io::{IsTerminal, Write};
use std::sync::Mutex;

/// Stage names and the last whole percent shown.
pub struct Bar {
    last: Mutex<(String, i64)>,
    terminal: bool,
}

impl Default for Bar {
    fn default() -> Self {
        Bar::new()
    }
}

impl Bar {
    pub fn new() -> Bar {
        Bar {
            last: Mutex::new((String::new(), -1)),
            terminal: std::io::stderr().is_terminal(),
        }
    }

    /// Shows `stage` at `fraction` (0 to 1).
    pub fn show(&self, stage: &str, fraction: f64) {
        let pct = (100.0 * fraction.clamp(0.0, 1.0)).floor() as i64;
        let Ok(mut last) = self.last.lock() else {
            return;
        };
        let new_stage = last.0 != stage;
        let every = if self.terminal { 1 } else { 10 };
        if !new_stage && pct / every == last.1 / every {
            return;
        }
        let mut err = std::io::stderr().lock();
        if self.terminal {
            let filled = (pct / 5) as usize;
            if new_stage && !last.0.is_empty() {
                let _ = writeln!(err);
            }
            let _ = write!(
                err,
                "\r{stage:>14} [{}{}] {pct:3} %",
                "#".repeat(filled),
                ".".repeat(20 - filled)
            );
            if pct == 100 {
                let _ = writeln!(err);
            }
        } else {
            let _ = writeln!(err, "{stage}: {pct} %");
        }
        let _ = err.flush();
        *last = (
            stage.to_string(),
            if pct == 100 && self.terminal { -1 } else { pct },
        );
        if pct == 100 && self.terminal {
            last.0.clear();
        }
    }
}
