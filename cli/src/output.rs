//! Where results go: human-readable text by default, one JSON object per line with `--json`
//! (a single-result command prints one object; `watch` prints one per sample, so a script can
//! read it line by line).

use std::io::Write;

use serde_json::Value;

use crate::error::CliError;

/// Prints results in the mode chosen on the command line.
#[derive(Debug, Clone, Copy)]
pub struct Out {
    json: bool,
}

impl Out {
    /// Text output, or JSON when `json`.
    pub fn new(json: bool) -> Out {
        Out { json }
    }

    /// Whether JSON was asked for.
    pub fn is_json(&self) -> bool {
        self.json
    }

    /// Prints one result: `human` as text, or `json` as one line. Flushed at once, so a reader
    /// of a pipe (a script, a `watch`) sees each result when it happens.
    pub fn emit(&self, human: impl std::fmt::Display, json: Value) -> Result<(), CliError> {
        let mut stdout = std::io::stdout().lock();
        let written = if self.json {
            writeln!(stdout, "{json}")
        } else {
            writeln!(stdout, "{human}")
        };
        // A closed pipe (`gripctl … watch | head -1`) ends the command; it is not a panic.
        written
            .and_then(|()| stdout.flush())
            .map_err(|e| CliError::output(&e))
    }
}
