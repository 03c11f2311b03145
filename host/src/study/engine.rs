//! The study engine: what every study (thesis, posture, accuracy, `hvs demo`) shares. A study
//! has its configuration and computes typed results, which write themselves ([`Report`]) through one
//! [`Files`] writer (CSVs, figures, pages from templates, the list of files written); [`run`]
//! is the one runner (progress, timing); [`table_text`] and [`table_markdown`] the one table
//! formatter.

use crate::data::output::write_bytes;
use crate::study::plot::{self, Figure};
use crate::study::template::fill;
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Where a run reports progress (a terminal's progress bars, or nothing).
pub trait Progress: Sync {
    /// A new stage with `units` steps.
    fn start(&self, name: &str, units: u64);
    /// One step of the current stage done.
    fn inc(&self);
    /// The current stage is done.
    fn finish(&self);
}

/// No progress output.
pub struct Quiet;

impl Progress for Quiet {
    fn start(&self, _: &str, _: u64) {}
    fn inc(&self) {}
    fn finish(&self) {}
}

/// The files of one study's run, written atomically into one directory (created if
/// missing); remembers the name of each file written, relative to that directory.
pub struct Files {
    dir: PathBuf,
    prefix: String,
    written: Vec<String>,
}

impl Files {
    /// A writer into `dir`, which is created if missing.
    pub fn new(dir: &Path) -> Result<Self> {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create the directory", dir.display()))?;
        Ok(Files { dir: dir.to_path_buf(), prefix: String::new(), written: Vec::new() })
    }

    /// The directory written into.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// A writer into the subdirectory `sub` (created if missing) whose names are listed as
    /// `sub/name`; [`Files::absorb`] takes its list back.
    pub fn sub(&self, sub: &str) -> Result<Self> {
        let mut f = Files::new(&self.dir.join(sub))?;
        f.prefix = format!("{}{sub}/", self.prefix);
        Ok(f)
    }

    /// Adds the files `sub` wrote to this writer's list.
    pub fn absorb(&mut self, sub: Files) {
        self.written.extend(sub.written);
    }

    /// Writes `name` with `bytes`.
    pub fn bytes(&mut self, name: &str, bytes: &[u8]) -> Result<()> {
        write_bytes(&self.dir.join(name), bytes)?;
        self.written.push(format!("{}{name}", self.prefix));
        Ok(())
    }

    /// Writes the CSV `name`: `header`, then each row's cells joined by commas.
    pub fn csv(&mut self, name: &str, header: &str, rows: &[Vec<String>]) -> Result<()> {
        let mut s = format!("{header}\n");
        for r in rows {
            let _ = writeln!(s, "{}", r.join(","));
        }
        self.bytes(name, s.as_bytes())
    }

    /// [`Files::csv`] with one row per item of `items`.
    pub fn rows<T>(
        &mut self,
        name: &str,
        header: &str,
        items: &[T],
        row: impl Fn(&T) -> Vec<String>,
    ) -> Result<()> {
        let rows: Vec<Vec<String>> = items.iter().map(row).collect();
        self.csv(name, header, &rows)
    }

    /// Writes `stem.svg` and `stem.png` of `fig`.
    pub fn figure(&mut self, stem: &str, fig: &Figure) -> Result<()> {
        for name in plot::write_figure(&self.dir, stem, fig)? {
            self.written.push(format!("{}{name}", self.prefix));
        }
        Ok(())
    }

    /// Writes the page `name` from `template` (called `template_name` in errors) with every
    /// placeholder filled from `values` ([`fill`]: a missing or unused value is an error,
    /// and then nothing is written).
    pub fn page(
        &mut self,
        name: &str,
        template_name: &str,
        template: &str,
        values: &[(&str, String)],
    ) -> Result<()> {
        let text = fill(template_name, template, values)?;
        self.bytes(name, text.as_bytes())
    }

    /// The names of the files written, in order.
    pub fn written(&self) -> &[String] {
        &self.written
    }

    /// The names of the files written, in order.
    pub fn into_written(self) -> Vec<String> {
        self.written
    }
}

/// A study's configuration with a reduced run (for tests): fewer restarts, nets and points.
pub trait Reduced {
    /// Whether this is the reduced run.
    fn quick(&self) -> bool;
    /// `full`, or `quick` on the reduced run.
    fn pick<T>(&self, full: T, quick: T) -> T {
        if self.quick() {
            quick
        } else {
            full
        }
    }
}

/// The results of one study, as the engine writes them: its files, then its page.
pub trait Report {
    /// The page [`Report::write`] writes last (the one to read first).
    const PAGE: &'static str;
    /// Writes the files; `total_s` is the run's wall time so far.
    fn write(&self, files: &mut Files, total_s: f64) -> Result<()>;
}

/// What a run did.
#[derive(Debug, Clone)]
pub struct Ran {
    /// The files written, relative to the output directory.
    pub files: Vec<String>,
    /// Worker threads used.
    pub threads: usize,
    /// Wall time of the whole run (s).
    pub seconds: f64,
}

impl Ran {
    /// The files written, counted by kind: `12 CSV, 9 SVG, 9 PNG, 1 MD` (in order of first
    /// appearance).
    pub fn kinds(&self) -> String {
        let mut kinds: Vec<(String, usize)> = Vec::new();
        for f in &self.files {
            let ext = Path::new(f)
                .extension()
                .map_or(String::new(), |e| e.to_string_lossy().to_uppercase());
            match kinds.iter_mut().find(|(k, _)| *k == ext) {
                Some((_, n)) => *n += 1,
                None => kinds.push((ext, 1)),
            }
        }
        kinds.iter().map(|(k, n)| format!("{n} {k}")).collect::<Vec<_>>().join(", ")
    }
}

/// Runs one study into `output` (created if missing): `compute` gives its results, reporting
/// to `progress`, then they write their files with the run's wall time.
pub fn run<R: Report>(
    output: &Path,
    progress: &dyn Progress,
    compute: impl FnOnce(&dyn Progress) -> Result<R>,
) -> Result<Ran> {
    let start = Instant::now();
    let mut files = Files::new(output)?;
    let results = compute(progress)?;
    results.write(&mut files, start.elapsed().as_secs_f64())?;
    let threads = rayon::current_num_threads();
    Ok(Ran { files: files.into_written(), threads, seconds: start.elapsed().as_secs_f64() })
}

/// Alignment of a markdown table's column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Align {
    /// `---`
    Left,
    /// `---:`
    Right,
}

/// A markdown table: the head, the alignment line (`align[k]`, left where missing), then one
/// row a line, every line ending in a newline.
pub fn table_markdown(head: &[&str], align: &[Align], rows: &[Vec<String>]) -> String {
    let mut s = format!("| {} |\n|", head.join(" | "));
    for k in 0..head.len() {
        s.push_str(match align.get(k) {
            Some(Align::Right) => "---:|",
            _ => "---|",
        });
    }
    s.push('\n');
    for r in rows {
        let _ = writeln!(s, "| {} |", r.join(" | "));
    }
    s
}

/// A plain-text table: columns padded to their widest cell, two spaces apart, a dashed line
/// under the head, trailing spaces trimmed.
pub fn table_text(head: &[&str], rows: &[Vec<String>]) -> String {
    let mut w: Vec<usize> = head.iter().map(|h| h.chars().count()).collect();
    for r in rows {
        for (k, c) in r.iter().enumerate() {
            if let Some(x) = w.get_mut(k) {
                *x = (*x).max(c.chars().count());
            }
        }
    }
    let mut s = String::new();
    let mut line = |cells: &mut dyn Iterator<Item = &str>| {
        let parts: Vec<String> = cells.zip(&w).map(|(c, w)| format!("{c:<w$}")).collect();
        let _ = writeln!(s, "{}", parts.join("  ").trim_end());
    };
    line(&mut head.iter().copied());
    let dashes: Vec<String> = w.iter().map(|n| "-".repeat(*n)).collect();
    line(&mut dashes.iter().map(String::as_str));
    for r in rows {
        line(&mut r.iter().map(String::as_str));
    }
    s
}

/// Small counts as words, as the prose uses them (two, three, four, six; digits otherwise).
pub fn number_word(n: usize) -> String {
    match n {
        2 => "two".into(),
        3 => "three".into(),
        4 => "four".into(),
        6 => "six".into(),
        _ => n.to_string(),
    }
}

/// Runs `job` on every item of `jobs` in parallel as the stage `name` of `progress`; the
/// results in the jobs' order, or the first error.
pub fn par_stage<J: Sync, R: Send>(
    progress: &dyn Progress,
    name: &str,
    jobs: &[J],
    job: impl Fn(&J) -> Result<R> + Sync,
) -> Result<Vec<R>> {
    use rayon::prelude::*;
    progress.start(name, jobs.len() as u64);
    let out = jobs.par_iter().map(|j| job(j).inspect(|_| progress.inc())).collect();
    progress.finish();
    out
}

/// Runs `f` and appends its wall time (s) to `stage_s` as the stage `name`.
pub fn timed<T>(
    stage_s: &mut Vec<(&'static str, f64)>,
    name: &'static str,
    f: impl FnOnce() -> Result<T>,
) -> Result<T> {
    let t = Instant::now();
    let out = f()?;
    stage_s.push((name, t.elapsed().as_secs_f64()));
    Ok(out)
}
