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
    let out = hvs().args(args).assert().success().get_output().stdout.clone();
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
    let out = hvs().args(args).assert().code(code).get_output().stderr.clone();
    String::from_utf8(out).expect("utf-8 stderr")
}

/// `hvs board detect --board board --captures captures -o out`.
pub fn detect_args<'a>(board: &'a Path, captures: &'a Path, out: &'a Path) -> Vec<&'a str> {
    let (b, c) = (s(board), s(captures));
    vec!["board", "detect", "--board", b, "--captures", c, "-o", s(out)]
}

/// Runs `hvs render --case 1 -o out --seed seed` and `rest`, asserting success.
pub fn render_case1(out: &Path, seed: &str, rest: &[&str]) {
    let mut args = vec!["render", "--case", "1", "-o", s(out), "--seed", seed];
    args.extend_from_slice(rest);
    ok(&args);
}

/// Runs `hvs train --data data -o model --restarts restarts`, asserting success.
pub fn train_restarts(data: &Path, model: &Path, restarts: &str) {
    ok(&["train", "--data", s(data), "-o", s(model), "--restarts", restarts]);
}

/// `verb --model model --left left --right right` and `rest` (`hvs locate`, `hvs depth`,
/// `hvs head look`).
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

/// A started quick experiment: the temporary directory, the output directory in it
/// (`<kind>`, created by the command) and the process.
pub struct QuickExperiment {
    /// Holds the output until the test ends.
    pub dir: tempfile::TempDir,
    /// Where the command writes.
    pub out: std::path::PathBuf,
    /// The running command.
    pub child: Child,
}

/// Starts `hvs experiment <kind> --quick ARGS -o <tmp>/<kind>` on one worker thread, so a
/// test can run the library on all threads meanwhile and compare the bytes.
pub fn spawn_quick_experiment(kind: &str, args: &[&str]) -> QuickExperiment {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join(kind);
    let child = std::process::Command::new(assert_cmd::cargo::cargo_bin("hvs"))
        .args(["experiment", kind, "--quick"])
        .args(args)
        .arg("-o")
        .arg(&out)
        .env("RAYON_NUM_THREADS", "1")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("hvs experiment starts");
    QuickExperiment { dir, out, child }
}

/// Waits for `child`, asserts success, returns (stdout, stderr).
pub fn wait_ok(child: Child) -> (String, Vec<u8>) {
    let output = child.wait_with_output().expect("the command ran");
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(output.status.success(), "{stdout}{}", String::from_utf8_lossy(&output.stderr));
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

/// `hvs simulate FLAGS -o OUT`, asserting success (`flags` split at white space).
pub fn simulate_into(flags: &str, out: &str) {
    ok_line(&format!("simulate {flags} -o {out}"));
}

/// `hvs train --data DATA -o MODEL FLAGS`, asserting success (`flags` split at white space).
pub fn train_into(data: &str, model: &str, flags: &str) {
    ok_line(&format!("train --data {data} -o {model} {flags}"));
}

/// A temporary directory whose files are named as strings (for [`ok_line`] command lines).
pub struct Scratch(tempfile::TempDir);

impl Scratch {
    /// A new empty directory (removed on drop).
    pub fn new() -> Self {
        Scratch(tempfile::TempDir::new().expect("a temporary directory"))
    }

    /// The path of file `name` in the directory.
    pub fn p(&self, name: &str) -> String {
        self.0.path().join(name).to_str().unwrap().to_string()
    }
}

/// A posture-aware model and its sets in `dir`: `train.csv` and `test.csv` from
/// `hvs simulate FLAGS --set train|test TRAIN_SET|TEST_SET`, and `m.hvsw` from
/// `hvs train --data train.csv TRAIN` (flags split at white space); returns `hvs info` of the
/// model.
pub fn posture_model(
    dir: &Scratch,
    flags: &str,
    train_set: &str,
    test_set: &str,
    train: &str,
) -> String {
    simulate_into(&format!("{flags} --set train {train_set}"), &dir.p("train.csv"));
    simulate_into(&format!("{flags} --set test {test_set}"), &dir.p("test.csv"));
    train_into(&dir.p("train.csv"), &dir.p("m.hvsw"), train);
    ok(&["info", &dir.p("m.hvsw")])
}

/// The text of `STEM.csv` written by two runs of a study, into `a` and `b`, after checking
/// that the two files are the same bytes.
pub fn same_csv(a: &Path, b: &Path, stem: &str) -> String {
    let csv = format!("{stem}.csv");
    let (x, y) = (read(&a.join(&csv)), read(&b.join(&csv)));
    assert!(x == y, "{csv} differs between two runs with the same seed");
    String::from_utf8(x).expect("utf-8 CSV")
}

/// The SVG text of plot `STEM` in `dir`, after checking that `STEM.png` is a PNG file and
/// that the SVG is one with text in it.
pub fn plot_svg(dir: &Path, stem: &str) -> String {
    let png = read(&dir.join(format!("{stem}.png")));
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{stem}.png");
    let svg = String::from_utf8(read(&dir.join(format!("{stem}.svg")))).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("<text"), "{stem}.svg");
    svg
}

/// A quarter-size case I rig (160 x 120), so the test renders and matches quickly.
pub const SMALL_RIG: &str = r#"{"phi_u_left": 71.459, "phi_u_right": 71.459, "alpha_left": 0, "alpha_right": 0,
  "beta0": 0, "phi0": 0, "u0": 80, "v0": 60, "width": 160, "height": 120}"#;

/// A scene of the small rig: a textured sphere moving at 5 cm/s before a wall at 300 cm
/// (`extra`: more top-level fields).
pub fn small_scene(dir: &Scratch, extra: &str) -> String {
    let text = format!(
        r#"{{ "rig": {SMALL_RIG}, "camera_fps": 30 {extra},
  "background": {{"z_cm": 300, "texture_seed": 1}},
  "objects": [ {{"shape": "sphere", "radius_cm": 8, "centre_cm": [10, -5, 90],
                "velocity_cm_s": [5, 0, 0], "texture_seed": 2}} ] }}"#
    );
    let p = dir.p("scene.json");
    std::fs::write(&p, text).unwrap();
    p
}

/// A stereo model of the small rig (the 9 x 6 board at 6 cm through it: the thesis' 4 x 3
/// board covers the middle of the view only, and the loop takes depths only from pixels
/// inside a model's training box).
pub fn small_model(dir: &Scratch) -> String {
    let rig = dir.p("rig.json");
    std::fs::write(&rig, SMALL_RIG).unwrap();
    let (data, m) = (dir.p("train.csv"), dir.p("m.hvsw"));
    ok(&["simulate", "--rig", &rig, "--set", "train", "--board", "9x6:6", "-o", &data]);
    ok(&["train", "--data", &data, "-o", &m, "--restarts", "1"]);
    m
}

/// The rows of CSV `text` split into fields, after checking its header is `header`.
pub fn csv_rows<'a>(text: &'a str, header: &str) -> Vec<Vec<&'a str>> {
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(header), "the header of:\n{text}");
    lines.map(|l| l.split(',').collect()).collect()
}

/// What `results` write (wall time 0) into a new temporary directory, and the
/// names of the files written.
pub fn written_by<R: hvs_host::study::engine::Report>(
    results: &R,
) -> (tempfile::TempDir, Vec<String>) {
    let dir = tempfile::tempdir().unwrap();
    let mut files = hvs_host::study::engine::Files::new(dir.path()).unwrap();
    results.write(&mut files, 0.0).unwrap();
    (dir, files.into_written())
}
