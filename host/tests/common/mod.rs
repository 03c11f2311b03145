//! Helpers shared by the integration tests that drive the built `hvs` binary.
// Each test file uses a different subset.
#![allow(dead_code)]

use assert_cmd::Command;
use predicates::prelude::*;
use std::path::Path;
use std::process::Child;

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

/// Runs `hvs` with `args`, asserts exit code `code`; returns stderr.
pub fn stderr_with_code<I, S>(args: I, code: i32) -> String
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    let out = hvs()
        .args(args)
        .assert()
        .code(code)
        .get_output()
        .stderr
        .clone();
    String::from_utf8(out).expect("utf-8 stderr")
}

/// `hvs board detect --board board --captures captures -o out`.
pub fn detect_args<'a>(board: &'a Path, captures: &'a Path, out: &'a Path) -> Vec<&'a str> {
    let (b, c) = (s(board), s(captures));
    vec![
        "board",
        "detect",
        "--board",
        b,
        "--captures",
        c,
        "-o",
        s(out),
    ]
}

/// Runs `hvs train --data data -o model --restarts restarts`, asserting success.
pub fn train_restarts(data: &Path, model: &Path, restarts: &str) {
    ok(&[
        "train",
        "--data",
        s(data),
        "-o",
        s(model),
        "--restarts",
        restarts,
    ]);
}

/// `verb --model model --left left --right right` and `rest` (`hvs locate`, `hvs head look`).
pub fn locate_args<'a>(
    verb: &[&'a str],
    model: &'a Path,
    left: &'a Path,
    right: &'a Path,
    rest: &[&'a str],
) -> Vec<&'a str> {
    let mut v = verb.to_vec();
    v.extend(["--model", s(model), "--left", s(left), "--right", s(right)]);
    v.extend_from_slice(rest);
    v
}

/// `p` as a `&str` argument.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// The bytes of `p`, or a panic naming it.
pub fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Starts `hvs experiment <kind> --quick --seed <seed> -o <out>` on one worker thread, so a
/// test can run the library on all threads meanwhile and compare the bytes.
pub fn spawn_quick_experiment(kind: &str, seed: u64, out: &Path) -> Child {
    std::process::Command::new(assert_cmd::cargo::cargo_bin("hvs"))
        .args([
            "experiment",
            kind,
            "--quick",
            "--seed",
            &seed.to_string(),
            "-o",
        ])
        .arg(out)
        .env("RAYON_NUM_THREADS", "1")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("hvs experiment starts")
}

/// Waits for `child`, asserts success, returns (stdout, stderr).
pub fn wait_ok(child: Child) -> (String, Vec<u8>) {
    let output = child.wait_with_output().expect("the command ran");
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(
        output.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&output.stderr)
    );
    (stdout, output.stderr)
}

/// [`ok`] of a command line split at white space (for arguments without spaces, such as
/// temporary paths): `ok_line(&format!("info {}", model))`.
pub fn ok_line(line: &str) -> String {
    ok(&line.split_whitespace().collect::<Vec<_>>())
}

/// [`fails`] of a command line split at white space.
pub fn fails_line(line: &str, want: &str) -> String {
    fails(&line.split_whitespace().collect::<Vec<_>>(), want)
}
