//! Reliability: outputs never destroy inputs, interrupted runs leave nothing,
//! strict input checks everywhere. Each test drives the built `hvs` binary.

use crate::common::{fails, hvs, ok, read, s, stderr_with_code};

use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use tempfile::TempDir;

/// Case 1's training and test sets and a model trained on them (one restart) in `dir`:
/// (train csv, test csv, model).
fn setup(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let (tr, te, m) = (dir.join("train.csv"), dir.join("test.csv"), dir.join("m.hvsw"));
    ok(&["simulate", "--case", "1", "--set", "train", "-o", s(&tr)]);
    ok(&["simulate", "--case", "1", "--set", "test", "-o", s(&te)]);
    ok(&["train", "--data", s(&tr), "-o", s(&m), "--restarts", "1"]);
    (tr, te, m)
}

/// `hvs predict --model m --points te -o out`.
fn predict_args<'a>(m: &'a Path, te: &'a Path, out: &'a str) -> Vec<&'a str> {
    vec!["predict", "--model", s(m), "--points", s(te), "-o", out]
}

/// `hvs image --model m --slot a --format bin` and `rest`.
fn image_args<'a>(m: &'a Path, rest: &[&'a str]) -> Vec<&'a str> {
    let mut v = vec!["image", "--model", s(m), "--slot", "a", "--format", "bin"];
    v.extend_from_slice(rest);
    v
}

fn mknod(path: &Path, major: u32, minor: u32) -> bool {
    let c = std::ffi::CString::new(s(path)).unwrap();
    // SAFETY: plain mknod(2) on a path in a temporary directory.
    let r = unsafe { libc::mknod(c.as_ptr(), libc::S_IFCHR | 0o666, libc::makedev(major, minor)) };
    if r != 0 {
        eprintln!(
            "note: mknod {}: {} (needs root); device case skipped",
            path.display(),
            std::io::Error::last_os_error()
        );
    }
    r == 0
}

fn mkfifo(path: &Path) {
    let c = std::ffi::CString::new(s(path)).unwrap();
    // SAFETY: plain mkfifo(3) on a path in a temporary directory.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o666) }, 0, "mkfifo");
}

fn file_type(p: &Path) -> std::fs::FileType {
    std::fs::symlink_metadata(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())).file_type()
}

// Item 1: an existing target that is not a regular file is written in place, never renamed
// over.
#[test]
fn outputs_onto_devices_fifos_and_links_are_written_in_place() {
    let dir = TempDir::new().unwrap();
    let (_, te, m) = setup(dir.path());
    let predict = |out: &Path| hvs().args(predict_args(&m, &te, s(out))).assert();
    let want = ok(&["predict", "--model", s(&m), "--points", s(&te)]);
    assert!(want.starts_with("u_l,v_l,u_r,v_r,x,y,z\n"), "{want}");

    // A FIFO: the reader gets the CSV, the FIFO stays a FIFO.
    let fifo = dir.path().join("fifo");
    mkfifo(&fifo);
    let f2 = fifo.clone();
    let reader = std::thread::spawn(move || std::fs::read_to_string(&f2).unwrap());
    predict(&fifo).success();
    // (Checked first: had the FIFO been replaced, the reader would wait forever.)
    assert!(file_type(&fifo).is_fifo(), "the FIFO was replaced");
    assert_eq!(reader.join().unwrap(), want);

    // A character device: null (1,3) swallows it; full (1,7) fails with the reason, exit 1.
    let null = dir.path().join("mynull");
    if mknod(&null, 1, 3) {
        predict(&null).success();
        assert!(file_type(&null).is_char_device(), "mynull was replaced");
        let full = dir.path().join("myfull");
        assert!(mknod(&full, 1, 7));
        let e = fails(&predict_args(&m, &te, s(&full)), "myfull: cannot write");
        assert!(e.contains("No space left"), "{e}");
        assert!(file_type(&full).is_char_device(), "myfull was replaced");
    }

    // A symbolic link stays a link; the file it names gets the CSV, atomically.
    let real = dir.path().join("real.csv");
    std::fs::write(&real, "old").unwrap();
    let link = dir.path().join("link.csv");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    predict(&link).success();
    assert!(file_type(&link).is_symlink(), "the link was replaced");
    assert_eq!(String::from_utf8(read(&real)).unwrap(), want);
    let to_null = dir.path().join("to_null");
    std::os::unix::fs::symlink("/dev/null", &to_null).unwrap();
    predict(&to_null).success();
    assert!(file_type(&to_null).is_symlink());
    assert!(file_type(Path::new("/dev/null")).is_char_device());
    // Nothing else was left in the directory.
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    names.sort();
    assert!(names.is_empty(), "left behind: {names:?}");
}

// Item 1: `-o /dev/stdout` is standard output (not a rename over /dev/stdout).
#[test]
fn output_to_dev_stdout_is_standard_output() {
    let dir = TempDir::new().unwrap();
    let (_, te, m) = setup(dir.path());
    let want = ok(&["predict", "--model", s(&m), "--points", s(&te)]);
    let got = ok(&predict_args(&m, &te, "/dev/stdout"));
    assert_eq!(got, want);
    assert!(file_type(Path::new("/dev/stdout")).is_symlink());
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/tests/fixtures").join(name)
}

// Item 2: an output that is one of the inputs is refused before any work, input untouched.
#[test]
fn an_output_that_is_an_input_is_refused() {
    let dir = TempDir::new().unwrap();
    let (tr, te, m) = setup(dir.path());
    let rig = dir.path().join("rig.json");
    std::fs::copy(fixture("cases.json"), &rig).unwrap();
    // Another name for the test set: a hard link, and a path through "./".
    let hard = dir.path().join("hard.csv");
    std::fs::hard_link(&te, &hard).unwrap();
    let dotted = dir.path().join(".").join("test.csv");
    // The rig file named as one of the files `hvs render` writes into its folder.
    let set = dir.path().join("set");
    std::fs::create_dir(&set).unwrap();
    let in_set = ["truth.csv", "board.json", "right03.png", "captures.csv"].map(|n| set.join(n));
    for p in &in_set {
        std::fs::copy(&rig, p).unwrap();
    }
    let mut cases: Vec<(Vec<&str>, &str, &Path)> = vec![
        (predict_args(&m, &te, s(&te)), "--points", &te),
        (predict_args(&m, &te, s(&hard)), "--points", &te),
        (predict_args(&m, &te, s(&dotted)), "--points", &te),
        (predict_args(&m, &te, s(&m)), "--model", &m),
        (vec!["train", "--data", s(&tr), "-o", s(&tr), "--restarts", "1"], "--data", &tr),
        (image_args(&m, &["-o", s(&m)]), "--model", &m),
        (
            vec!["simulate", "--rig", s(&rig), "--case", "1", "--set", "train", "-o", s(&rig)],
            "--rig",
            &rig,
        ),
        (
            vec![
                "head",
                "--connect",
                "tcp:127.0.0.1:9",
                "estimate",
                "--points",
                s(&te),
                "-o",
                s(&te),
            ],
            "--points",
            &te,
        ),
    ];
    for p in &in_set {
        cases.push((vec!["render", "--rig", s(p), "--case", "1", "-o", s(&set)], "--rig", p));
    }
    for (args, flag, input) in cases {
        let before = read(input);
        let e = fails(&args, &format!("is also the {flag} input"));
        assert!(e.contains("error: -o "), "{e}");
        assert_eq!(read(input), before, "{args:?} changed {}", input.display());
    }
}

/// Temporary files (`.NAME...tmp`) in `dir`.
fn temp_files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.') && n.ends_with(".tmp"))
        .collect();
    v.sort();
    v
}

/// Starts a long `hvs simulate` into `out`, waits until its temporary file exists, sends
/// `signal`; returns the exit status and the temporary files seen while it ran.
///
/// The child starts with SIGINT, SIGTERM and SIGHUP at their defaults, as from a terminal,
/// except those in `ignored` (as `nohup` ignores SIGHUP).
/// It would otherwise inherit the test runner's dispositions: a runner started as a
/// background job of a script (`cmd &`) ignores SIGINT, `hvs` rightly keeps an ignored
/// signal ignored, and the child would finish its write and exit 0.
fn interrupt_a_write(
    out: &Path,
    signal: libc::c_int,
    ignored: &'static [libc::c_int],
) -> (std::process::ExitStatus, Vec<String>) {
    let args = ["simulate", "--case", "1", "--set", "volume", "--points", "1000000", "-o", s(out)];
    interrupt_when(&args, out.parent().unwrap(), 1, signal, ignored)
}

/// Runs `hvs args`, waits until at least `temps` temporary files are in `dir`, sends
/// `signal` (see [`interrupt_a_write`]); returns the exit status and the temporary files seen.
fn interrupt_when(
    args: &[&str],
    dir: &Path,
    temps: usize,
    signal: libc::c_int,
    ignored: &'static [libc::c_int],
) -> (std::process::ExitStatus, Vec<String>) {
    use std::os::unix::process::CommandExt;
    let mut cmd = std::process::Command::new(assert_cmd::cargo::cargo_bin("hvs"));
    cmd.args(args).stdout(std::process::Stdio::null()).stderr(std::process::Stdio::null());
    // SAFETY: signal(2) is async-signal-safe, so it may run between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
                let to = if ignored.contains(&sig) { libc::SIG_IGN } else { libc::SIG_DFL };
                if libc::signal(sig, to) == libc::SIG_ERR {
                    return Err(std::io::Error::last_os_error());
                }
            }
            Ok(())
        });
    }
    let mut child = cmd.spawn().unwrap();
    // Not a timing assertion: the loop only waits for the writes to begin.
    let seen = loop {
        let t = temp_files(dir);
        if t.len() >= temps {
            break t;
        }
        if let Some(st) = child.try_wait().unwrap() {
            panic!("hvs {args:?} ended ({st}) before {temps} temporary files were seen");
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    };
    // SAFETY: kill(2) on our own child.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
    (child.wait().unwrap(), seen)
}

/// Every file of `dir` (a flat folder) with its bytes, sorted by name.
fn folder(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (e.file_name().to_string_lossy().into_owned(), std::fs::read(e.path()).unwrap())
        })
        .collect();
    v.sort();
    v
}

// A rerun of `hvs render` or `hvs collect` into the last run's folder, stopped by a signal
// while it writes its images: the folder is as the last run left it (not this run's images
// beside the last `board.json` or `CAPTURES.csv`), and no temporary file is left. `collect`
// writes its images from several threads at once.
#[test]
fn an_interrupted_rerun_leaves_the_last_set_as_it_was() {
    use std::os::unix::process::ExitStatusExt;
    let dir = TempDir::new().unwrap();
    let set = dir.path().join("set");
    let depths = "65,75,85,95,105,115,125,135,145,155,165";
    let render = |square: &'static str| -> Vec<&'static str> {
        let v = vec!["render", "--case", "1", "--depths", depths, "--square-cm", square];
        v
    };
    let mut first = render("6");
    first.extend(["-o", s(&set)]);
    ok(&first);
    let before = folder(&set);
    assert_eq!(before.len(), 2 * 11 + 3, "{:?}", before.iter().map(|f| &f.0).collect::<Vec<_>>());
    for (sig, temps) in [(libc::SIGINT, 1), (libc::SIGTERM, 9)] {
        let mut again = render("4");
        again.extend(["-o", s(&set)]);
        let (st, seen) = interrupt_when(&again, &set, temps, sig, &[]);
        assert_eq!(st.signal(), Some(sig), "{st}");
        assert!(seen.len() >= temps, "{seen:?}");
        assert_eq!(folder(&set), before, "signal {sig} after {} temporary files", seen.len());
    }
    // A whole rerun of fewer depths says which of the last set's images stay beside it.
    let o = crate::common::hvs()
        .args(["render", "--case", "1", "--depths", "95", "-o", s(&set)])
        .output()
        .unwrap();
    assert!(o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("20 image(s) of an earlier set stay beside this one (left02.png"), "{e}");

    let b = dir.path().join("board.json");
    let p = dir.path().join("positions.csv");
    let scene = dir.path().join("scene.json");
    std::fs::write(&b, r#"{"pattern": "chessboard", "inner_corners": [7, 5], "square_cm": 4.0}"#)
        .unwrap();
    std::fs::write(&p, "x,y,z\n0,0,85\n").unwrap();
    std::fs::write(
        &scene,
        r#"{"rig": {"case": 3}, "camera_fps": 30, "background": {"z_cm": 300, "texture_seed": 1}}"#,
    )
    .unwrap();
    let collected = dir.path().join("collected");
    let collect = |seed: &'static str| {
        let v = [
            "collect",
            "--board",
            s(&b),
            "--positions",
            s(&p),
            "--postures",
            "random",
            "--posture-count",
            "60",
            "--scene",
            s(&scene),
            "--supersample",
            "2",
            "--seed",
            seed,
            "-o",
            s(&collected),
        ];
        v.to_vec()
    };
    ok(&collect("1"));
    let before = folder(&collected);
    assert!(before.len() > 20, "{} files", before.len());
    for (sig, temps) in [(libc::SIGINT, 2), (libc::SIGINT, 20), (libc::SIGTERM, 40)] {
        let (st, seen) = interrupt_when(&collect("2"), &collected, temps, sig, &[]);
        assert_eq!(st.signal(), Some(sig), "{st}");
        assert_eq!(folder(&collected), before, "signal {sig} after {} temporary files", seen.len());
    }
}

// `hvs track --record` stopped by SIGINT, SIGTERM or SIGHUP (a closed terminal) while it
// records: the loop ends, and the log and the record of the frames so far are written whole
// (the frames wait in temporary files in the folder as they are taken, not in memory); its
// files may not replace an input or the log.
#[test]
fn an_interrupted_recording_is_whole() {
    use crate::common::{small_model, small_scene, Scratch};
    let dir = Scratch::new();
    let (m, sc) = (small_model(&dir), small_scene(&dir, ""));
    for (k, sig) in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP].into_iter().enumerate() {
        let (log, rec) = (dir.p(&format!("log{k}.csv")), dir.p(&format!("rec{k}")));
        std::fs::create_dir(&rec).unwrap();
        let args = [
            "track",
            "--model",
            &m,
            "--scene",
            &sc,
            "--seconds",
            "60",
            "--log",
            &log,
            "--record",
            &rec,
        ];
        let (st, seen) = interrupt_when(&args, Path::new(&rec), 6, sig, &[]);
        assert_eq!(st.code(), Some(130), "signal {sig}: {st}");
        assert!(seen.len() >= 6, "{seen:?}");
        let frames = std::fs::read_to_string(&log).unwrap().lines().count() - 1;
        let files = folder(Path::new(&rec));
        let names: Vec<&str> = files.iter().map(|f| f.0.as_str()).collect();
        assert_eq!(files.len(), 2 * frames + 1, "signal {sig}: {frames} frames, {names:?}");
        let captures =
            String::from_utf8(files.iter().find(|f| f.0 == "CAPTURES.csv").unwrap().1.clone())
                .unwrap();
        assert_eq!(captures.lines().count(), frames + 1, "{captures}");
        assert!(names.contains(&format!("right{:04}.png", frames - 1).as_str()), "{names:?}");
    }
    // The record's files would replace the scene: refused before the run.
    let rec = dir.p("rec0");
    let inside = Path::new(&rec).join("CAPTURES.csv");
    std::fs::copy(&sc, &inside).unwrap();
    let before = std::fs::read(&inside).unwrap();
    let log = dir.p("log.csv");
    let e = stderr_with_code(
        [
            "track",
            "--model",
            &m,
            "--scene",
            s(&inside),
            "--seconds",
            "0.1",
            "--log",
            &log,
            "--record",
            &rec,
        ],
        2,
    );
    assert!(e.contains("the record's files would replace the --scene file"), "{e}");
    assert_eq!(std::fs::read(&inside).unwrap(), before);
}

// Item 3: SIGINT and SIGTERM remove the temporary file; the process dies of the signal.
#[test]
fn interrupted_writes_leave_nothing() {
    use std::os::unix::process::ExitStatusExt;
    for sig in [libc::SIGINT, libc::SIGTERM] {
        let dir = TempDir::new().unwrap();
        let out = dir.path().join("int.csv");
        let (st, seen) = interrupt_a_write(&out, sig, &[]);
        assert_eq!(st.signal(), Some(sig), "{st}");
        assert_eq!(seen.len(), 1, "{seen:?}");
        assert!(seen[0].starts_with(".int.csv.hvs-"), "{seen:?}");
        assert_eq!(temp_files(dir.path()), Vec::<String>::new(), "signal {sig}");
        assert!(!out.exists());
    }
}

// A signal ignored when `hvs` starts (`nohup` and SIGHUP) stays ignored: the write goes on
// and lands whole.
#[test]
fn an_ignored_signal_stays_ignored() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("int.csv");
    let (st, seen) = interrupt_a_write(&out, libc::SIGHUP, &[libc::SIGHUP]);
    assert!(st.success(), "{st}");
    assert_eq!(seen.len(), 1, "{seen:?}");
    assert_eq!(temp_files(dir.path()), Vec::<String>::new());
    let rows = std::fs::read_to_string(&out).unwrap().lines().count();
    assert_eq!(rows, 1_000_001, "a header and every point");
}

// Item 3: after SIGKILL the temporary file stays (nothing can run), named with the dead pid;
// the next write into the same directory removes it, and leaves other files alone.
#[test]
fn the_next_write_removes_what_a_killed_run_left() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("int.csv");
    let (_, seen) = interrupt_a_write(&out, libc::SIGKILL, &[]);
    assert_eq!(temp_files(dir.path()), seen, "SIGKILL cannot clean up");
    // Not ours (no pid), and ours but alive (this test's pid): kept.
    let foreign = ".notes.csv.tmp".to_string();
    let alive = format!(".x.csv.hvs-{}.abcdef.tmp", std::process::id());
    std::fs::write(dir.path().join(&foreign), "keep").unwrap();
    std::fs::write(dir.path().join(&alive), "keep").unwrap();
    let next = dir.path().join("next.csv");
    ok(&["simulate", "--case", "1", "--set", "test", "-o", s(&next)]);
    let mut want = vec![foreign, alive];
    want.sort();
    assert_eq!(temp_files(dir.path()), want);
}

/// Writes `header` and `rows` as a CSV in `dir`.
fn csv(dir: &Path, name: &str, header: &str, rows: &[String]) -> PathBuf {
    let p = dir.join(name);
    let mut t = format!("{header}\n");
    for r in rows {
        t.push_str(r);
        t.push('\n');
    }
    std::fs::write(&p, t).unwrap();
    p
}

/// The data rows of the case-1 training fixture (12 per depth, depths 65, 85, ..., 165).
fn train_rows() -> Vec<String> {
    std::fs::read_to_string(fixture("case1_train.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(str::to_string)
        .collect()
}

// Item 5: sets that cannot determine the net, a single depth, and absurd values are refused
// with the reason; the thesis' two-depth experiment (24 rows x 3 outputs, 43 parameters)
// still trains.
#[test]
fn degenerate_and_absurd_training_sets_are_refused() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let h = "u_l,v_l,u_r,v_r,x,y,z";
    let rows = train_rows();
    let m = d.join("m.hvsw");
    let train = |p: &Path, want: &str| {
        let e = fails(&["train", "--data", s(p), "-o", s(&m), "--restarts", "1"], want);
        assert!(!m.exists(), "{e}");
        e
    };
    let one = csv(d, "one.csv", h, &rows[..1]);
    let e = train(&one, "1 row x 3 outputs = 3 equations cannot determine");
    assert!(e.contains("43 parameters"), "{e}");
    let flat = csv(d, "flat.csv", h, &rows[..12]);
    train(&flat, "12 rows x 3 outputs = 36 equations");
    // Enough rows for the Z-only net (31 parameters), all at Z = 65: one depth.
    let mut same_depth = rows[..12].to_vec();
    same_depth.extend(rows[..12].iter().map(|r| r.replacen("330,", "331,", 1)));
    same_depth.extend(rows[..12].iter().map(|r| r.replacen("231,", "232,", 1)));
    let flat = csv(d, "flat65.csv", h, &same_depth);
    train(&flat, "all 36 rows lie at one depth (z = 65 cm)");

    let mut bad = rows.clone();
    bad[3] = bad[3].replacen("356", "1e30", 1);
    assert!(bad[3].contains("1e30"), "{}", bad[3]);
    let p = csv(d, "pixel.csv", h, &bad);
    let want = "pixel.csv:5: column \"u_l\": 1e30 px is not a value";
    train(&p, want);
    // `hvs predict` and `hvs eval` refuse it too (they answered for it).
    let two = csv(d, "two.csv", h, &rows[..24]);
    ok(&["train", "--data", s(&two), "-o", s(&m), "--restarts", "1"]);
    fails(&["predict", "--model", s(&m), "--points", s(&p)], want);
    fails(&["eval", "--model", s(&m), "--data", s(&p)], want);
    std::fs::remove_file(&m).unwrap();
    let mut bad = rows.clone();
    bad[7] = bad[7].replacen(",65.0000", ",1e30", 1);
    let p = csv(d, "z.csv", h, &bad);
    train(&p, "z.csv:9: column \"z\"");

    // Values beyond f32: one message for train and predict alike.
    let mut bad = rows.clone();
    bad[2] = bad[2].replacen("347", "1e39", 1);
    let p = csv(d, "huge.csv", h, &bad);
    let want = "huge.csv:4: column \"u_l\": 1e39 does not fit the f32 the model computes in";
    train(&p, want);
    let two = csv(d, "two.csv", h, &rows[..24]);
    let out = ok(&["train", "--data", s(&two), "-o", s(&m), "--restarts", "1"]);
    assert!(out.contains("on 24 points"), "{out}");
    fails(&["predict", "--model", s(&m), "--points", s(&p)], want);
}

// Several --data files train as their rows in one file would; their errors name the file and
// line they come from; sets of different kinds or image sizes, or a file given twice, are
// refused.
#[test]
fn several_training_sets_join_as_one() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let h = "u_l,v_l,u_r,v_r,x,y,z";
    let rows = train_rows();
    let all = csv(d, "all.csv", h, &rows);
    let a = csv(d, "a.csv", h, &rows[..36]);
    let b = csv(d, "b.csv", h, &rows[36..]);
    let (one, two) = (d.join("one.hvsw"), d.join("two.hvsw"));
    ok(&["train", "--data", s(&all), "-o", s(&one), "--restarts", "2"]);
    let out = ok(&["train", "--data", s(&a), "--data", s(&b), "-o", s(&two), "--restarts", "2"]);
    assert!(out.contains("on 72 points of ") && out.contains("a.csv and 1 more file"), "{out}");
    assert_eq!(read(&one), read(&two), "the same rows, the same model");

    let m = d.join("m.hvsw");
    let train = |files: &[&Path], want: &str| {
        let mut args = vec!["train", "-o", s(&m), "--restarts", "1"];
        for f in files {
            args.extend(["--data", s(f)]);
        }
        let e = fails(&args, want);
        assert!(!m.exists(), "{e}");
    };
    // A bad value in the second file: its own name and line.
    let mut bad = rows[36..].to_vec();
    let mut fields: Vec<&str> = bad[4].split(',').collect();
    fields[1] = "1e30";
    bad[4] = fields.join(",");
    let c = csv(d, "c.csv", h, &bad);
    train(&[&a, &c], "c.csv:6: column \"v_l\"");
    train(&[&a, &d.join("./a.csv")], "given twice");
    let hard = d.join("hard.csv");
    std::fs::hard_link(&a, &hard).unwrap();
    train(&[&a, &hard], "given twice");
    // Another kind of set, or images of another size.
    let joints = "u_l,v_l,u_r,v_r,x,y,z,neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan";
    let with_joints: Vec<String> = rows[36..].iter().map(|r| format!("{r},0,0,0,0,0")).collect();
    let j = csv(d, "j.csv", joints, &with_joints);
    train(&[&a, &j], "join sets of one kind");
    let sized: Vec<String> = rows[36..].iter().map(|r| format!("{r},640,480")).collect();
    let z = csv(d, "z.csv", &format!("{h},image_width,image_height"), &sized);
    train(&[&a, &z], "z.csv: 640x480 px images, ");
    // An output onto any of the inputs.
    let e = fails(
        &["train", "--data", s(&a), "--data", s(&b), "-o", s(&b)],
        "is also the --data input",
    );
    assert_eq!(read(&b), read(&csv(d, "b2.csv", h, &rows[36..])), "{e}");
}

// Item 7: a rig file with a key given twice is refused, naming the key.
#[test]
fn rig_json_with_a_duplicate_key_is_refused() {
    let dir = TempDir::new().unwrap();
    let rig = dir.path().join("rig.json");
    std::fs::write(
        &rig,
        r#"{"phi_u_left": 285.8, "phi_u_right": 228.7, "alpha_left": -0.0455,
            "alpha_right": 0.0455, "beta0": 0.0087, "phi0": 0.0087, "u0": 320, "u0": 100}"#,
    )
    .unwrap();
    let e = fails(&["simulate", "--rig", s(&rig), "--set", "test"], "duplicate key \"u0\"");
    assert!(e.contains("rig.json"), "{e}");
    let cases = dir.path().join("cases.json");
    let text = std::fs::read_to_string(fixture("cases.json")).unwrap();
    std::fs::write(&cases, text.replacen("\"phi0\"", "\"phi0\": 0.1, \"phi0\"", 1)).unwrap();
    fails(
        &["simulate", "--rig", s(&cases), "--case", "1", "--set", "test"],
        "duplicate key \"phi0\" in \"cases\".\"1\"",
    );
}

/// A file with only an ELF header: 32-bit little-endian, machine `machine`.
fn fake_elf(p: &Path, machine: u16) {
    let mut h = vec![0u8; 52];
    h[..4].copy_from_slice(b"\x7fELF");
    h[4] = 1;
    h[5] = 1;
    h[6] = 1;
    h[16] = 2;
    h[18..20].copy_from_slice(&machine.to_le_bytes());
    std::fs::write(p, h).unwrap();
}

// Item 4: `hvs emulate` checks the model, firmware, servo-log directory and listen address
// before it starts (QEMU is never run: --qemu names a program that does not exist).
#[test]
fn emulate_checks_its_inputs_before_it_starts() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let (_, _, m) = setup(d);
    let arm = d.join("fw.elf");
    fake_elf(&arm, 40);
    let x86 = d.join("x86.elf");
    fake_elf(&x86, 62);
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let busy = port.local_addr().unwrap().to_string();
    let free = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().to_string()
    };
    let log = d.join("s.log");
    let nodir = d.join("nodir").join("s.log");
    let emulate = |model: &Path, fw: &Path, log: &Path, listen: &str, want: &str| {
        fails(
            &[
                "emulate",
                "--model",
                s(model),
                "--firmware",
                s(fw),
                "--servo-log",
                s(log),
                "--listen",
                listen,
                "--qemu",
                "/nonexistent/qemu-system-arm",
            ],
            want,
        )
    };
    let e = emulate(d, &arm, &log, &free, "Is a directory");
    assert!(e.contains("--model"), "{e}");
    let e = emulate(&m, &m, &log, &free, "not an ELF file");
    assert!(e.contains("--firmware"), "{e}");
    emulate(&m, &x86, &log, &free, "e_machine 62");
    emulate(&m, &arm, &nodir, &free, "the directory");
    emulate(&m, &arm, &m, &free, "--servo-log");
    let e = emulate(&m, &arm, &log, &busy, "cannot listen there");
    assert!(e.contains(&busy), "{e}");
    emulate(&m, &arm, &log, "nonsense", "not a HOST:PORT address");
    // A valid model with more bytes after it than a slot holds: it would spill into slot B.
    let spill = d.join("spill.hvsw");
    let mut bytes = std::fs::read(&m).unwrap();
    bytes.resize(128 * 1024 + 1, 0xff);
    std::fs::write(&spill, &bytes).unwrap();
    emulate(&spill, &arm, &log, &free, "more than a weight slot holds (131072 bytes)");
    // With every input right, the next failure is QEMU itself.
    emulate(&m, &arm, &log, &free, "cannot run");
    assert!(!log.exists());
    drop(port);
}

// Item 6: every command reads CSVs with the one reader: a UTF-8 BOM is accepted, a
// duplicated column and a header-only file are errors; `hvs head estimate` checks its
// input and output before it connects.
#[test]
fn every_command_reads_csvs_alike() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let (tr, _, m) = setup(d);
    let text = std::fs::read_to_string(&tr).unwrap();
    let bom = d.join("bom.csv");
    std::fs::write(&bom, format!("\u{feff}{text}")).unwrap();
    let header_only = d.join("hdr.csv");
    std::fs::write(&header_only, text.lines().next().unwrap()).unwrap();
    let dup = d.join("dup.csv");
    std::fs::write(
        &dup,
        text.replacen("u_l,v_l,u_r,v_r,x,y,z", "u_l,v_l,u_r,v_r,x,y,z,u_l", 1)
            .replace('\n', ",1\n"),
    )
    .unwrap();
    let m2 = d.join("m2.hvsw");
    let no_head = "tcp:127.0.0.1:9";
    let commands = |f: &Path| -> Vec<Vec<String>> {
        let f = s(f).to_string();
        let m = s(&m).to_string();
        [
            vec!["train", "--restarts", "1", "-o", s(&m2), "--data", &f],
            vec!["predict", "--model", &m, "--points", &f],
            vec!["eval", "--model", &m, "--data", &f],
            vec!["head", "--connect", no_head, "estimate", "--points", &f],
        ]
        .iter()
        .map(|v| v.iter().map(|x| x.to_string()).collect())
        .collect()
    };
    for args in commands(&bom) {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        if args[0] == "head" {
            // Read fine; the failure is the missing head.
            fails(&args, "cannot connect");
        } else {
            ok(&args);
        }
    }
    for (f, want) in [
        (&header_only, "hdr.csv: no data rows after the header"),
        (&dup, "dup.csv:1: column \"u_l\" appears twice in the header"),
    ] {
        for args in commands(f) {
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            fails(&args, want);
        }
    }
    let nodir = d.join("nodir").join("x.csv");
    let e = fails(
        &["head", "--connect", no_head, "estimate", "--points", s(&tr), "-o", s(&nodir)],
        "the directory",
    );
    assert!(e.contains("nodir/x.csv") && !e.contains(".x.csv."), "{e}");
}

/// Runs `hvs args` with stdout into /dev/full; returns (exit code, stderr).
fn to_dev_full(args: &[&str]) -> (Option<i32>, String) {
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let out = std::process::Command::new(assert_cmd::cargo::cargo_bin("hvs"))
        .args(args)
        .stdout(full)
        .output()
        .unwrap();
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

// Item 9: messages that say what is wrong and where.
#[test]
fn messages_name_the_real_problem() {
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let (tr, _, m) = setup(d);
    // Negative numbers get the range, not "unexpected argument".
    for (args, want) in [
        (
            vec!["simulate", "--case", "1", "--set", "volume", "--points", "-5"],
            "-5 is out of range: expected a whole number from 0 to",
        ),
        (
            image_args(&m, &["--generation", "-1", "-o", "x.bin"]),
            "-1 is out of range: expected a whole number from 0 to 4294967295",
        ),
        (vec!["train", "--data", s(&tr), "-o", "x.hvsw", "--restarts", "-3"], "-3 is out of range"),
    ] {
        let e = stderr_with_code(&args, 2);
        assert!(e.contains(want), "{args:?}: {e}");
        assert!(!e.contains("unexpected argument"), "{e}");
    }
    // The noise, not the rig.
    let e = fails(
        &["simulate", "--case", "1", "--set", "test", "--noise-px", "1e30"],
        "--noise-px must be a finite number >= 0 and at most the image size (640 px)",
    );
    assert!(!e.contains("case 1"), "{e}");
    // A model that is a directory.
    fails(&["emulate", "--model", s(d)], "Is a directory");
    let e =
        stderr_with_code(["head", "--connect", "tcp:127.0.0.1:9", "--timeout-ms", "0", "ping"], 2);
    assert!(e.contains("--timeout-ms must be at least 1"), "{e}");
    // No head given (bad usage, exit 2), or none there: both ways are named.
    let e = stderr_with_code(["head", "ping"], 2);
    assert!(e.contains("--connect tcp:HOST:PORT") && e.contains("--port DEVICE"), "{e}");
    for (bad, want) in [
        ("tcp:127.0.0.1", "expected tcp:HOST:PORT"),
        ("tcp:h:99999", "is not a number from 0 to 65535"),
        ("", "--port: empty"),
    ] {
        for flag in ["--connect", "--port"] {
            let e = stderr_with_code(["head", flag, bad, "ping"], 2);
            assert!(
                e.contains(want) || (flag == "--connect" && bad.is_empty()),
                "{flag} {bad:?}: {e}"
            );
        }
    }
    fails(&["head", "--connect", "tcp:127.0.0.1:9", "ping"], "--port DEVICE");
    // A head that accepts the connection and never answers (as QEMU does for a second client).
    let busy = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = format!("tcp:{}", busy.local_addr().unwrap());
    fails(&["head", "--connect", &addr, "--timeout-ms", "300", "ping"], "busy with another client");
    drop(busy);
    // Errors on stdout name stdout.
    let (code, e) = to_dev_full(&["simulate", "--case", "1", "--set", "train"]);
    assert_eq!(code, Some(1), "{e}");
    assert!(e.contains("cannot write to stdout") && e.contains("No space left"), "{e}");
    // The model was written; only the summary failed, and the message says so.
    let m2 = d.join("m2.hvsw");
    let (code, e) = to_dev_full(&["train", "--data", s(&tr), "-o", s(&m2), "--restarts", "1"]);
    assert_eq!(code, Some(1), "{e}");
    assert!(e.contains("but cannot print the summary to stdout") && e.contains("m2.hvsw"), "{e}");
    assert_eq!(read(&m2), read(&m), "the model was written in full");
    let (code, e) = to_dev_full(&[
        "image",
        "--model",
        s(&m),
        "--slot",
        "a",
        "--format",
        "bin",
        "-o",
        s(&d.join("a.bin")),
    ]);
    assert_eq!(code, Some(1), "{e}");
    assert!(e.contains("cannot write to stdout") && !e.contains("panicked"), "{e}");
    // The algorithm as --algo spells it.
    let info = ok(&["info", s(&m)]);
    assert!(info.contains("training:    lm, seed 0"), "{info}");
    let out = ok(&["train", "--data", s(&tr), "-o", s(&m2), "--restarts", "1"]);
    assert!(out.starts_with("trained 4-5-3 inverse-depth-skip (lm) on 72 points"), "{out}");
}

// Item 8: a CRC-valid blob with a huge weight gives estimates far outside the training
// outputs; `hvs predict` flags them (the head's in_range uses the same
// `runtime::head::outputs_in_range`, tested in hvs-shared and under QEMU).
#[test]
fn estimates_of_a_damaged_model_are_flagged_out_of_range() {
    use hvs_shared::runtime::blob::{self, MAX_BLOB_LEN};
    let dir = TempDir::new().unwrap();
    let d = dir.path();
    let (_, te, m) = setup(d);
    let good = blob::decode(&read(&m)).unwrap();
    let clean = hvs()
        .args(["predict", "--model", s(&m), "--points", s(&te)])
        .assert()
        .success()
        .get_output()
        .stderr
        .clone();
    assert!(!String::from_utf8_lossy(&clean).contains("far outside"));
    let bad_m = d.join("bad.hvsw");
    let mut huge_and_finite = 0;
    for k in 0..good.params.len() {
        let mut b = good.clone();
        b.params[k] = 3.4e38;
        let mut buf = vec![0u8; MAX_BLOB_LEN];
        let n = b.encode(&mut buf).unwrap();
        std::fs::write(&bad_m, &buf[..n]).unwrap();
        let out =
            hvs().args(["predict", "--model", s(&bad_m), "--points", s(&te)]).output().unwrap();
        if !out.status.success() {
            continue; // the weight overflowed the estimate: "cannot estimate this point"
        }
        let csv = String::from_utf8(out.stdout).unwrap();
        // Absurd: a coordinate beyond 10 km, or a depth under 1 cm (the inverse-depth family
        // divides by a huge 1/Z output).
        let huge = csv.lines().skip(1).any(|l| {
            let f: Vec<f32> = l.split(',').skip(4).filter_map(|v| v.parse().ok()).collect();
            f.iter().any(|v| v.abs() > 1e6) || f.get(2).is_some_and(|z| z.abs() < 1.0)
        });
        if huge {
            huge_and_finite += 1;
            let e = String::from_utf8(out.stderr).unwrap();
            assert!(
                e.contains("estimates lie far outside the outputs the model was trained on"),
                "param {k}: {e}"
            );
            assert!(e.contains("test.csv:2"), "{e}");
        }
    }
    assert!(huge_and_finite > 0, "no weight gave a huge finite estimate");
}

// Item 10: `hvs demo`'s table fits 100 columns (two tables); the README gives the command
// that installs the firmware target next to the firmware build.
#[test]
fn demo_fits_100_columns_and_the_readme_names_the_target_install() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("d");
    let stdout = ok(&["demo", "-o", s(&out), "--restarts", "1"]);
    for l in stdout.lines().filter(|l| !l.starts_with("wrote ")) {
        assert!(l.chars().count() <= 100, "{} columns: {l}", l.chars().count());
    }
    assert_eq!(stdout.lines().filter(|l| l.starts_with("IV ")).count(), 2);
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../README.md"))
            .unwrap();
    let at =
        readme.find("cargo run --profile firmware -p hvs-firmware").expect("the firmware build");
    let before = &readme[..at];
    let hint = before.rfind("rustup toolchain install").expect("the install command");
    assert!(at - hint < 400, "the install command is not next to the firmware build");
    assert!(readme.contains("can't find crate for `core`"));
}
