//! `CAPTURES.csv`: one row per stereo pair of board photos.
//!
//! Columns by name, any order: `left,right` (image paths relative to the CSV's folder),
//! optionally `z` (board depth, cm), `x,y` (board centre, cm, default 0), and any others
//! (the five joint columns among them), which are passed through to every corner row of the
//! pair. Errors name the file, the line and the column.

use super::csv::{
    check_row_len, check_unique_names, csv_error, csv_reader, joint_columns_present,
    missing_column, number, LineCounter,
};
use super::dataset::JOINT_COLUMNS;
use anyhow::{bail, Context, Result};
use hvs_shared::runtime::gaze::Joints;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One stereo pair of a capture set.
#[derive(Debug, Clone, PartialEq)]
pub struct Capture {
    /// 1-based line of the row in the CSV.
    pub line: u64,
    /// The left image as written in the CSV.
    pub left_name: String,
    /// The right image as written in the CSV.
    pub right_name: String,
    /// The left image's path (relative to the CSV's folder).
    pub left: PathBuf,
    /// The right image's path.
    pub right: PathBuf,
    /// Board depth (cm), if the set gives it.
    pub z: Option<f64>,
    /// Board centre X, Y (cm).
    pub xy: [f64; 2],
    /// The passed-through fields, in the order of [`CaptureSet::extra_columns`].
    pub extra: Vec<String>,
}

/// A capture set read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct CaptureSet {
    /// The file, as given.
    pub path: PathBuf,
    /// Whether every row gives `z` (all or none do).
    pub has_z: bool,
    /// The columns passed through (joint columns first, in their canonical order, then the
    /// others in file order).
    pub extra_columns: Vec<String>,
    /// The pairs.
    pub captures: Vec<Capture>,
}

impl CaptureSet {
    /// `file:line` of a capture, for messages.
    pub fn at(&self, c: &Capture) -> String {
        format!("{}:{}", self.path.display(), c.line)
    }

    /// A capture's name for people: `file:line (left image, right image)` (`hvs board detect`'s
    /// report, `hvs view`'s list of pairs).
    pub fn name(&self, c: &Capture) -> String {
        format!("{} ({}, {})", self.at(c), c.left_name, c.right_name)
    }
}

/// One pair to write into a `CAPTURES.csv` ([`captures_csv`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CaptureRow<'a> {
    /// The left image, relative to the CSV's folder.
    pub left: &'a str,
    /// The right image.
    pub right: &'a str,
    /// The board centre X, Y, Z (cm).
    pub centre: [f64; 3],
    /// The posture the pair was taken at (written when the set has joint columns).
    pub joints: Joints,
}

/// `CAPTURES.csv` as [`read`] reads it, one row per pair: `left,right,z,x,y` (the board
/// centre, cm; left out when some row has none, a non-finite centre: a `hvs track --record`
/// of a scene without objects) and, `with_joints`, the [`JOINT_COLUMNS`] of each pair's
/// posture; numbers in their shortest round-trip form. The one writer of the format (`hvs
/// render`, `hvs collect`, `hvs track --record`).
pub fn captures_csv(rows: &[CaptureRow<'_>], with_joints: bool) -> String {
    let mut s = String::with_capacity(96 * (rows.len() + 1));
    let centres = rows.iter().all(|r| r.centre.iter().all(|v| v.is_finite()));
    s.push_str(if centres { "left,right,z,x,y" } else { "left,right" });
    if with_joints {
        s.push(',');
        s.push_str(&JOINT_COLUMNS.join(","));
    }
    s.push('\n');
    for r in rows {
        let [x, y, z] = r.centre;
        let _ = write!(s, "{},{}", r.left, r.right);
        if centres {
            let _ = write!(s, ",{z},{x},{y}");
        }
        if with_joints {
            for v in r.joints.0 {
                let _ = write!(s, ",{v}");
            }
        }
        s.push('\n');
    }
    s
}

/// The columns `hvs board detect` writes before the capture's own (`POINTS.csv`): a
/// captures column of one of these names would be passed through as a duplicate.
pub const DETECTED_COLUMNS: [&str; 7] = ["capture", "i", "j", "u_l", "v_l", "u_r", "v_r"];

const OWN: [&str; 5] = ["left", "right", "z", "x", "y"];

/// Reads `path`.
pub fn read(path: &Path) -> Result<CaptureSet> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).with_context(|| format!("{file}: cannot read"))?;
    let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(&bytes);
    let dir = path
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf);
    let mut lines_of = LineCounter::new(bytes);
    let mut rdr = csv_reader(bytes);
    let header = rdr.headers().map_err(|e| csv_error(&file, e))?.clone();
    let hl = lines_of.line_at(header.position().map_or(0, |p| p.byte()));
    let names: Vec<String> = header.iter().map(str::to_string).collect();
    if names.iter().all(String::is_empty) {
        bail!("{file}: empty file (expected a header row naming the columns left,right)");
    }
    check_unique_names(&file, hl, &names, false)?;
    let find = |c: &str| names.iter().position(|n| n == c);
    let need = |c: &str| find(c).ok_or_else(|| missing_column(&file, hl, c, &names));
    let (li, ri) = (need("left")?, need("right")?);
    let (zi, xi, yi) = (find("z"), find("x"), find("y"));
    let present_joints = joint_columns_present(&file, hl, find)?;
    if let Some((k, n)) = names.iter().enumerate().find(|(_, n)| {
        DETECTED_COLUMNS.contains(&n.as_str())
            || super::csv::IMAGE_SIZE_COLUMNS.contains(&n.as_str())
    }) {
        bail!(
            "{file}:{hl}: column {} \"{n}\": hvs board detect writes a column of that name itself ({},{}); rename or drop it",
            k + 1,
            DETECTED_COLUMNS.join(","),
            super::csv::IMAGE_SIZE_COLUMNS.join(",")
        );
    }
    let mut extra_columns: Vec<String> = present_joints.iter().map(|s| s.to_string()).collect();
    for n in &names {
        if !OWN.contains(&n.as_str()) && !JOINT_COLUMNS.contains(&n.as_str()) && !n.is_empty() {
            extra_columns.push(n.clone());
        }
    }
    let extra_idx: Vec<usize> = extra_columns.iter().map(|c| find(c).unwrap_or(0)).collect();
    let mut captures: Vec<Capture> = Vec::new();
    let mut rec = csv::StringRecord::new();
    while rdr.read_record(&mut rec).map_err(|e| csv_error(&file, e))? {
        let line = lines_of.line_at(rec.position().map_or(0, |p| p.byte()));
        check_row_len(&file, line, rec.len(), header.len())?;
        let name = |k: usize, col: &str| -> Result<String> {
            let s = rec[k].to_string();
            if s.is_empty() {
                bail!("{file}:{line}: column \"{col}\" is empty");
            }
            Ok(s)
        };
        let (left_name, right_name) = (name(li, "left")?, name(ri, "right")?);
        let opt_num = |k: Option<usize>, col: &str| -> Result<Option<f64>> {
            match k {
                Some(k) => Ok(Some(number(&file, line, col, rec[k].as_bytes())?)),
                None => Ok(None),
            }
        };
        let z = opt_num(zi, "z")?;
        if let Some(z) = z {
            if z <= 0.0 {
                bail!("{file}:{line}: column \"z\": {z} cm is not a depth in front of the head (must be > 0)");
            }
        }
        let xy = [opt_num(xi, "x")?.unwrap_or(0.0), opt_num(yi, "y")?.unwrap_or(0.0)];
        let most = crate::data::validate::MAX_ABS_CM;
        for (v, col) in [xy[0], xy[1], z.unwrap_or(0.0)].into_iter().zip(["x", "y", "z"]) {
            if v.abs() > most {
                bail!(
                    "{file}:{line}: column \"{col}\": {} cm is not a place a head's cameras see (|{col}| must be at most {most} cm, as in a training set)",
                    crate::fmt::given(v)
                );
            }
        }
        let mut extra = Vec::with_capacity(extra_idx.len());
        for (k, c) in extra_idx.iter().zip(&extra_columns) {
            if JOINT_COLUMNS.contains(&c.as_str()) {
                number(&file, line, c, rec[*k].as_bytes())?;
            }
            extra.push(rec[*k].to_string());
        }
        // The same pair twice would give its corners twice, weighing that board double in
        // training (a file given twice to `hvs train` is refused for the same reason).
        if let Some(c) =
            captures.iter().find(|c| (&c.left_name, &c.right_name) == (&left_name, &right_name))
        {
            bail!(
                "{file}:{line}: the pair {left_name}, {right_name} is line {}'s again: each pair once",
                c.line
            );
        }
        captures.push(Capture {
            line,
            left: dir.join(&left_name),
            right: dir.join(&right_name),
            left_name,
            right_name,
            z,
            xy,
            extra,
        });
    }
    if captures.is_empty() {
        bail!("{file}: no captures after the header");
    }
    Ok(CaptureSet { path: path.to_path_buf(), has_z: zi.is_some(), extra_columns, captures })
}

#[cfg(test)]
mod tests {
    use super::*;
    use anyhow::anyhow;

    fn read_text(text: &str) -> Result<CaptureSet> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("captures.csv");
        std::fs::write(&p, text).unwrap();
        read(&p).map_err(|e| {
            anyhow!("{}", format!("{e:#}").replace(&dir.path().display().to_string(), "DIR"))
        })
    }

    #[test]
    fn reads_pairs_depths_and_passes_other_columns_through() {
        let s =
            read_text("\u{feff}note,right,left,z\nfar,r1.png,l1.png,165\nnear,r2.png,l2.png,65\n")
                .unwrap();
        assert!(s.has_z);
        assert_eq!(s.extra_columns, ["note"]);
        assert_eq!(s.captures.len(), 2);
        let c = &s.captures[1];
        assert_eq!(
            (c.line, c.left_name.as_str(), c.z, c.xy),
            (3, "l2.png", Some(65.0), [0.0, 0.0])
        );
        assert!(c.right.ends_with("r2.png"));
        assert_eq!(c.extra, ["near"]);
    }

    #[test]
    fn joints_come_first_and_must_be_complete() {
        let h = JOINT_COLUMNS.join(",");
        let s = read_text(&format!("left,right,{h}\na,b,1,2,3,4,5\n")).unwrap();
        assert_eq!(s.extra_columns, JOINT_COLUMNS);
        assert!(!s.has_z);
        let e = read_text("left,right,neck_pan\na,b,1\n").unwrap_err().to_string();
        assert!(e.contains(":1:") && e.contains("neck_tilt"), "{e}");
        let e = read_text(&format!("left,right,{h}\na,b,1,2,x,4,5\n")).unwrap_err().to_string();
        assert!(e.contains(":2:") && e.contains("eye_tilt"), "{e}");
    }

    /// What the writer writes the reader reads: with centres, and without (a `hvs track
    /// --record` of a scene without objects: before, `NaN` depths the reader refused).
    #[test]
    fn written_sets_read_back_with_and_without_centres() {
        let row = |centre: [f64; 3]| CaptureRow {
            left: if centre[0].is_nan() { "l2.png" } else { "l.png" },
            right: "r.png",
            centre,
            joints: Joints([1.5, 0.0, -2.0, 0.25, 3.0]),
        };
        let with = captures_csv(&[row([1.0, -2.0, 65.0])], true);
        let s = read_text(&with).unwrap();
        assert!(s.has_z);
        assert_eq!((s.captures[0].z, s.captures[0].xy), (Some(65.0), [1.0, -2.0]));
        assert_eq!(s.captures[0].extra, ["1.5", "0", "-2", "0.25", "3"]);
        let without = captures_csv(&[row([1.0, -2.0, 65.0]), row([f64::NAN; 3])], true);
        assert!(without.starts_with("left,right,neck_pan,"), "{without}");
        let s = read_text(&without).unwrap();
        assert!(!s.has_z);
        assert_eq!(s.captures.len(), 2);
        assert_eq!(s.captures[1].extra, ["1.5", "0", "-2", "0.25", "3"]);
    }

    #[test]
    fn bad_files_name_line_and_column() {
        for (text, want) in [
            ("", "empty file"),
            ("left,right\n", "no captures"),
            ("left,z\na,65\n", "missing column \"right\""),
            ("left,right,z\na,b,abc\n", ":2: column \"z\""),
            ("left,right,z\na,b,-5\n", ":2: column \"z\""),
            // Finite but absurd (QA: z = 1e30 came out as "left and right swapped").
            ("left,right,z\na,b,1e30\n", ":2: column \"z\": 1e30 cm is not a place"),
            ("left,right,z,x,y\na,b,65,0,-2e5\n", ":2: column \"y\": -200000 cm"),
            ("left,right\n,b\n", ":2: column \"left\" is empty"),
            ("left,right,left\na,b,c\n", "appears twice"),
            ("left,right\na,b,c\n", ":2: row has 3 fields"),
            ("left,right,z\na,b,65\nc,d,85\na,b,65\n", ":4: the pair a, b is line 2's again"),
        ] {
            let e = read_text(text).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?}: {e}");
        }
    }
}
