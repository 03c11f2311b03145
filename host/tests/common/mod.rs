//! Helpers shared by the integration tests that drive the built `hvs` binary.
// Each test file uses a different subset.
#![allow(dead_code)]

use assert_cmd::Command;
use predicates::prelude::*;
use std::path::Path;

/// The built `hvs` binary.
pub fn hvs() -> Command {
    Command::cargo_bin("hvs").expect("the hvs binary is built")
}

/// Runs `hvs` with `args` and asserts success; returns stdout.
pub fn ok(args: &[&str]) -> String {
    let out = hvs()
        .args(args)
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    String::from_utf8(out).expect("utf-8 stdout")
}

/// Runs `hvs` with `args`, asserts exit code 1, an empty stdout and a one-line stderr
/// `error: <message>` that contains `want`; returns the message.
pub fn fails(args: &[&str], want: &str) -> String {
    let out = hvs()
        .args(args)
        .assert()
        .code(1)
        .stdout(predicate::str::is_empty())
        .get_output()
        .stderr
        .clone();
    let err = String::from_utf8(out).expect("utf-8 stderr");
    assert_eq!(err.lines().count(), 1, "one line expected: {err}");
    assert!(err.starts_with("error: "), "{err}");
    assert!(err.contains(want), "expected {want:?} in {err:?}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// `p` as a `&str` argument.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}
