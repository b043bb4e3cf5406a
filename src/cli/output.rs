//! Printing that survives a closed pipe: `say!` writes a line to standard output and turns a
//! closed pipe into [`CliError::ClosedPipe`], which ends the command quietly.

use super::CliError;
use std::io::Write;

/// Writes one line to standard output.
pub fn line(args: std::fmt::Arguments) -> Result<(), CliError> {
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{args}").and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(CliError::ClosedPipe),
        Err(e) => Err(CliError::Failed(format!(
            "cannot write to standard output: {e}"
        ))),
    }
}

/// Writes a line to standard error; a closed standard error is ignored.
pub fn note(args: std::fmt::Arguments) {
    let _ = writeln!(std::io::stderr().lock(), "{args}");
}

/// Reports a command's failure on standard error.
pub fn error(e: &CliError) {
    note(format_args!("error: {e}"));
}

/// `say!("...", args)`: one line to standard output; `?`-returns on a closed pipe.
macro_rules! say {
    ($($t:tt)*) => {
        $crate::cli::output::line(format_args!($($t)*))?
    };
}

/// `tell!("...", args)`: one line to standard error, never failing.
macro_rules! tell {
    ($($t:tt)*) => {
        $crate::cli::output::note(format_args!($($t)*))
    };
}
