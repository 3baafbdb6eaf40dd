//! Command lines that do not parse: one line on stderr and exit status 2, like every other
//! failure is one line (status 1); `--help` and `--version` still print as usual.

mod common;

use common::gripctl;

fn one_error_line(run: &common::Run) -> &str {
    assert_eq!(run.code, Some(2), "{run:#?}");
    let lines: Vec<&str> = run.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{run:#?}");
    assert!(lines[0].starts_with("gripctl: "), "{run:#?}");
    lines[0]
}

#[tokio::test]
async fn unparsable_command_lines_are_one_line() {
    let run = gripctl(&["smartgrasp", "--bogus", "state"]).await;
    let line = one_error_line(&run);
    assert!(line.contains("unexpected argument '--bogus'"), "{line}");

    let run = gripctl(&["smartgrasp", "project"]).await;
    let line = one_error_line(&run);
    assert!(
        line.contains("required arguments were not provided: <INDEX>"),
        "{line}"
    );

    let run = gripctl(&["--timeout", "0", "smartgrasp", "state"]).await;
    let line = one_error_line(&run);
    assert!(line.contains("a duration must be positive"), "{line}");

    let run = gripctl(&["smartgrasp", "grasp", "--mode", "sideways", "--json"]).await;
    one_error_line(&run);
    let json: serde_json::Value = serde_json::from_str(run.stdout.trim()).expect("JSON error");
    assert_eq!(json["error"]["kind"], "argument");
}

#[tokio::test]
async fn help_and_version_still_print() {
    let run = gripctl(&["--version"]).await;
    assert_eq!(run.code, Some(0));
    assert!(run.stdout.starts_with("gripctl "), "{run:?}");
    let run = gripctl(&["sim", "--help"]).await;
    assert_eq!(run.code, Some(0));
    assert!(run.stdout.contains("smartgrasp"), "{run:?}");
}
