//! The study engine: the file writer, the runner, the table formatters.

use anyhow::Result;
use hvs_host::study::engine::{
    number_word, run, table_markdown, table_text, Align, Files, Progress, Quiet, Report,
};
use std::path::PathBuf;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hvs-engine-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn the_writer_lists_the_files_it_wrote() {
    let d = tmp("list");
    let mut f = Files::new(&d).unwrap();
    f.csv("a.csv", "x,y", &[vec!["1".into(), "2".into()]]).unwrap();
    let mut s = f.sub("part").unwrap();
    s.rows("b.csv", "n", &[3, 4], |n| vec![n.to_string()]).unwrap();
    f.absorb(s);
    f.page("P.md", "p.md", "n = {n}\n", &[("n", "5".into())]).unwrap();
    assert_eq!(f.written(), ["a.csv", "part/b.csv", "P.md"]);
    assert_eq!(std::fs::read_to_string(d.join("a.csv")).unwrap(), "x,y\n1,2\n");
    assert_eq!(std::fs::read_to_string(d.join("part/b.csv")).unwrap(), "n\n3\n4\n");
    assert_eq!(std::fs::read_to_string(d.join("P.md")).unwrap(), "n = 5\n");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_page_with_an_unfilled_placeholder_fails_and_writes_nothing() {
    let d = tmp("unfilled");
    let mut f = Files::new(&d).unwrap();
    let e = f.page("P.md", "p.md", "{a} and {b}\n", &[("a", "1".into())]).unwrap_err().to_string();
    assert_eq!(e, "template p.md, line 1: no value for {b}");
    assert!(f.written().is_empty());
    assert!(!d.join("P.md").exists());
    let _ = std::fs::remove_dir_all(&d);
}

struct Count(Vec<usize>);

impl Report for Count {
    const PAGE: &'static str = "COUNT.md";
    fn write(&self, files: &mut Files, _: f64) -> Result<()> {
        files.rows("count.csv", "k", &self.0, |k| vec![k.to_string()])?;
        files.page(Self::PAGE, "count.md", "{n} rows\n", &[("n", self.0.len().to_string())])
    }
}

fn count(n: usize, progress: &dyn Progress) -> Result<Count> {
    progress.start("count", n as u64);
    let v = (0..n).inspect(|_| progress.inc()).collect();
    progress.finish();
    Ok(Count(v))
}

#[test]
fn the_runner_computes_then_writes() {
    let d = tmp("run");
    let ran = run(&d.join("out"), &Quiet, |p| count(3, p)).unwrap();
    assert_eq!(ran.files, ["count.csv", "COUNT.md"]);
    assert_eq!(ran.kinds(), "1 CSV, 1 MD");
    assert_eq!(ran.threads, rayon::current_num_threads());
    assert_eq!(std::fs::read_to_string(d.join("out/count.csv")).unwrap(), "k\n0\n1\n2\n");
    assert_eq!(std::fs::read_to_string(d.join("out/COUNT.md")).unwrap(), "3 rows\n");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn tables() {
    let rows = vec![
        vec!["I".to_string(), "1.0 %".to_string()],
        vec!["IV".to_string(), "12.25 %".to_string()],
    ];
    assert_eq!(
        table_markdown(&["case", "e_ma"], &[Align::Left, Align::Right], &rows),
        "| case | e_ma |\n|---|---:|\n| I | 1.0 % |\n| IV | 12.25 % |\n"
    );
    assert_eq!(
        table_text(&["case", "e_ma"], &rows),
        "case  e_ma\n----  -------\nI     1.0 %\nIV    12.25 %\n"
    );
    assert_eq!(
        (number_word(2), number_word(6), number_word(7)),
        ("two".into(), "six".into(), "7".into())
    );
}
