//! CSV in: reading point sets with errors that name file, line and column (outputs are written
//! by [`crate::data::output`]).
//!
//! Input format: a header row, then one row per point. Columns are found by name in any
//! order (`u_l,v_l,u_r,v_r`; `x,y,z` where ground truth is needed; the five joint-angle
//! columns of [`crate::data::dataset::JOINT_COLUMNS`] for posture-aware sets); other columns are
//! ignored, but for `image_width,image_height` ([`IMAGE_SIZE_COLUMNS`], which `hvs board
//! detect` writes): the size of the images the pixels come from, the same in every row
//! ([`Table::image_size`]). Surrounding spaces are trimmed; blank lines are skipped.

use crate::data::dataset::{Dataset, JOINT_COLUMNS, PIXEL_COLUMNS, TARGET_COLUMNS};
use anyhow::{anyhow, bail, Context, Result};
use hvs_shared::runtime::blob::InputKind;
use hvs_shared::runtime::protocol::StereoPoint;
use std::io::Read;
use std::path::{Path, PathBuf};

/// Which input columns to read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Inputs {
    /// The four pixel columns only (joint columns, if any, are ignored).
    Stereo,
    /// The four pixel columns and the five joint columns, all required.
    StereoJoints,
    /// The five joint columns too when the header has all of them (a header with only some
    /// of them is an error).
    Auto,
}

impl From<InputKind> for Inputs {
    fn from(k: InputKind) -> Self {
        match k {
            InputKind::Stereo => Inputs::Stereo,
            InputKind::StereoJoints => Inputs::StereoJoints,
        }
    }
}

/// A point set read from a file, with the line number of every row for later messages.
#[derive(Debug, Clone)]
pub struct Table {
    /// The file, as given.
    pub path: PathBuf,
    /// The rows.
    pub data: Dataset,
    /// 1-based line number of each row in the file.
    pub lines: Vec<u64>,
    /// The size (width, height) of the images the pixels were found in, when the file says
    /// ([`IMAGE_SIZE_COLUMNS`]).
    pub image_size: Option<(u16, u16)>,
    /// The files joined after `path` ([`Table::join`]), each with the index of its first row.
    pub more: Vec<(PathBuf, usize)>,
}

/// The columns that give the size of the images a point set's pixels come from.
pub const IMAGE_SIZE_COLUMNS: [&str; 2] = ["image_width", "image_height"];

impl Table {
    /// `file:line` of row `i`, for messages.
    pub fn at(&self, i: usize) -> String {
        let path =
            self.more.iter().rev().find(|(_, first)| i >= *first).map_or(&self.path, |m| &m.0);
        match self.lines.get(i) {
            Some(l) => format!("{}:{l}", path.display()),
            None => path.display().to_string(),
        }
    }

    /// The file's name, or the first file's and how many more were joined to it.
    pub fn name(&self) -> String {
        match self.more.len() {
            0 => self.path.display().to_string(),
            n => format!(
                "{} and {n} more file{}",
                self.path.display(),
                if n == 1 { "" } else { "s" }
            ),
        }
    }

    /// The rows of `tables` in their order, as one set: the same inputs (pixels, or pixels
    /// and joints) and targets in each, and the same image size where any says one.
    pub fn join(tables: Vec<Table>) -> Result<Table> {
        let mut parts = tables.into_iter();
        let Some(mut out) = parts.next() else {
            bail!("no point set to join");
        };
        let kind = |t: &Table| match t.data.n_inputs {
            4 => "the four pixel columns",
            _ => "the pixel and joint columns",
        };
        for t in parts {
            let (first, this) = (out.path.display(), t.path.display());
            if t.data.n_inputs != out.data.n_inputs {
                bail!("{this}: has {}, {first} {}: join sets of one kind", kind(&t), kind(&out));
            }
            if t.data.targets.is_empty() != out.data.targets.is_empty() {
                bail!("{this}: the x,y,z columns are in one of {this} and {first} only");
            }
            if t.image_size != out.image_size {
                let size = |s: Option<(u16, u16)>| {
                    s.map_or("no image size".to_string(), |(w, h)| format!("{w}x{h} px images"))
                };
                bail!(
                    "{this}: {}, {first}: {}: join sets from images of one size",
                    size(t.image_size),
                    size(out.image_size)
                );
            }
            let start = out.data.len();
            out.more.push((t.path.clone(), start));
            for r in 0..t.data.len() {
                out.data.push(t.data.row(r), t.data.targets.get(r).copied());
            }
            out.lines.extend(&t.lines);
            out.more.extend(t.more.into_iter().map(|(p, k)| (p, k + start)));
        }
        Ok(out)
    }
}

/// Reads a point set from `path`. With `targets`, the `x,y,z` columns are required.
pub fn read_set(path: &Path, inputs: Inputs, targets: bool) -> Result<Table> {
    let file =
        std::fs::File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    read_set_from(path, file, inputs, targets)
}

/// The `u_l,v_l,u_r,v_r` columns of a CSV (by header name, other columns ignored) as the
/// head's [`StereoPoint`]s, each with its 1-based line number: the same reader (and the same
/// errors) as `hvs predict`, values rounded to f32 as host inference does.
pub fn read_stereo_points(path: &Path) -> Result<Vec<(usize, StereoPoint)>> {
    let t = read_set(path, Inputs::Stereo, false)?;
    Ok((0..t.data.len())
        .map(|i| {
            let r = t.data.row(i);
            (
                t.lines[i] as usize,
                StereoPoint {
                    u_l: r[0] as f32,
                    v_l: r[1] as f32,
                    u_r: r[2] as f32,
                    v_r: r[3] as f32,
                },
            )
        })
        .collect())
}

/// Reads a point set from any reader; `name` is used in messages.
pub fn read_set_from<R: Read>(
    name: &Path,
    mut reader: R,
    inputs: Inputs,
    targets: bool,
) -> Result<Table> {
    let file = name.display().to_string();
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes).with_context(|| format!("{file}: cannot read"))?;
    let mut lines_of = LineCounter::new(&bytes);
    let mut rdr = csv_reader(&bytes);
    let header = rdr.byte_headers().map_err(|e| csv_error(&file, e))?.clone();
    if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
        bail!("{file}: empty file (expected a header row naming the columns u_l,v_l,u_r,v_r)");
    }
    let hl = lines_of.line_at(header.position().map_or(0, |p| p.byte()));
    let names: Vec<String> =
        header.iter().map(|h| String::from_utf8_lossy(h).into_owned()).collect();
    check_unique_names(&file, hl, &names, true)?;
    let find = |c: &str| names.iter().position(|n| n == c);
    let require = |c: &str| find(c).ok_or_else(|| missing_column(&file, hl, c, &names));
    let with_joints = match inputs {
        Inputs::Stereo => false,
        Inputs::StereoJoints => true,
        Inputs::Auto => !joint_columns_present(&file, hl, find)?.is_empty(),
    };
    let mut in_cols: Vec<(usize, &str)> = Vec::new();
    for c in PIXEL_COLUMNS {
        in_cols.push((require(c)?, c));
    }
    if with_joints {
        for c in JOINT_COLUMNS {
            in_cols.push((require(c)?, c));
        }
    }
    let size_cols = match IMAGE_SIZE_COLUMNS.map(find) {
        [Some(w), Some(h)] => Some([w, h]),
        [None, None] => None,
        _ => bail!(
            "{file}:{hl}: the columns {} go together: give both or neither",
            IMAGE_SIZE_COLUMNS.join(" and ")
        ),
    };
    let mut image_size: Option<(u16, u16)> = None;
    let mut tgt_cols: Vec<(usize, &str)> = Vec::new();
    if targets {
        for c in TARGET_COLUMNS {
            tgt_cols.push((require(c)?, c));
        }
    }
    let kind = if with_joints { InputKind::StereoJoints } else { InputKind::Stereo };
    let mut data = Dataset::new(kind);
    let mut lines = Vec::new();
    let mut rec = csv::ByteRecord::new();
    let mut row = vec![0.0f64; in_cols.len()];
    loop {
        match rdr.read_byte_record(&mut rec) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(csv_error(&file, e)),
        }
        let line = lines_of.line_at(rec.position().map_or(0, |p| p.byte()));
        check_row_len(&file, line, rec.len(), header.len())?;
        for (slot, (col, cname)) in row.iter_mut().zip(&in_cols) {
            *slot = number(&file, line, cname, &rec[*col])?;
        }
        let target = if targets {
            let mut t = [0.0; 3];
            for (slot, (col, cname)) in t.iter_mut().zip(&tgt_cols) {
                *slot = number(&file, line, cname, &rec[*col])?;
            }
            if t[2] <= 0.0 {
                bail!(
                    "{file}:{line}: column \"z\": {} cm is not a depth in front of the head (must be > 0)",
                    t[2]
                );
            }
            Some(t)
        } else {
            None
        };
        if let Some(cols) = size_cols {
            let [w, h] = [0, 1].map(|k| {
                let (c, name) = (cols[k], IMAGE_SIZE_COLUMNS[k]);
                let t = String::from_utf8_lossy(&rec[c]);
                t.parse::<u16>().ok().filter(|v| *v > 0).ok_or_else(|| {
                    anyhow!("{file}:{line}: column \"{name}\": {t:?} is not an image size in pixels (1 to 65535)")
                })
            });
            let size = (w?, h?);
            match image_size {
                Some(first) if first != size => bail!(
                    "{file}:{line}: images of {}x{} px, where line {} has {}x{}: one point set comes from images of one size",
                    size.0,
                    size.1,
                    lines[0],
                    first.0,
                    first.1
                ),
                _ => image_size = Some(size),
            }
        }
        data.push(&row, target);
        lines.push(line);
    }
    if data.is_empty() {
        bail!("{file}: no data rows after the header");
    }
    Ok(Table { path: name.to_path_buf(), data, lines, image_size, more: Vec::new() })
}

/// 1-based line numbers of records from their byte offsets. The csv crate's own line count
/// is off after blank lines and CRLF endings, and its record offsets may point at the previous
/// line's terminator, so terminators are skipped first. Offsets must not decrease.
pub(crate) struct LineCounter<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: u64,
}

impl<'a> LineCounter<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        LineCounter { bytes, pos: 0, line: 1 }
    }

    pub(crate) fn line_at(&mut self, offset: u64) -> u64 {
        let mut start = (offset as usize).min(self.bytes.len());
        while start < self.bytes.len() && matches!(self.bytes[start], b'\r' | b'\n') {
            start += 1;
        }
        if start > self.pos {
            // A line ends at "\n", "\r\n" or a lone "\r" (the csv crate accepts all three).
            let bytes = self.bytes;
            self.line += (self.pos..start)
                .filter(|&i| {
                    bytes[i] == b'\n' || (bytes[i] == b'\r' && bytes.get(i + 1) != Some(&b'\n'))
                })
                .count() as u64;
            self.pos = start;
        }
        self.line
    }
}

pub(crate) fn number(file: &str, line: u64, column: &str, field: &[u8]) -> Result<f64> {
    let text = std::str::from_utf8(field)
        .map_err(|_| anyhow!("{file}:{line}: column \"{column}\" is not valid UTF-8"))?;
    if text.is_empty() {
        bail!("{file}:{line}: column \"{column}\" is empty");
    }
    let v: f64 = text
        .parse()
        .map_err(|_| anyhow!("{file}:{line}: column \"{column}\": \"{text}\" is not a number"))?;
    if !v.is_finite() {
        bail!("{file}:{line}: column \"{column}\": \"{text}\" is not a finite number");
    }
    if v.abs() > f32::MAX as f64 {
        bail!(
            "{file}:{line}: column \"{column}\": {text} does not fit the f32 the model computes in"
        );
    }
    Ok(v)
}

/// The CSV reader every table of `hvs` is read with: a header row, rows of any length (checked
/// by [`check_row_len`], naming the line), fields trimmed.
pub(crate) fn csv_reader(bytes: &[u8]) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(bytes)
}

/// A column named twice in the header (line `hl`) is an error; with `skip_empty`, unnamed
/// columns may repeat.
pub(crate) fn check_unique_names(
    file: &str,
    hl: u64,
    names: &[String],
    skip_empty: bool,
) -> Result<()> {
    for (i, n) in names.iter().enumerate() {
        if !(skip_empty && n.is_empty()) && names[..i].contains(n) {
            bail!("{file}:{hl}: column \"{n}\" appears twice in the header");
        }
    }
    Ok(())
}

/// The error of a header (line `hl`) without column `c`.
pub(crate) fn missing_column(file: &str, hl: u64, c: &str, names: &[String]) -> anyhow::Error {
    if names.iter().all(|n| n.trim().is_empty()) {
        return anyhow!("{file}: empty file (expected a header row naming the column \"{c}\")");
    }
    anyhow!(
        "{file}:{hl}: missing column \"{c}\" (the header has: {})",
        // A quoted name may hold a line break: the message stays one line.
        names.join(",").replace(['\n', '\r'], " ")
    )
}

/// The joint columns the header (line `hl`) has, `find` giving a column's index: all of them
/// or none (a posture-aware set needs all).
pub(crate) fn joint_columns_present(
    file: &str,
    hl: u64,
    find: impl Fn(&str) -> Option<usize>,
) -> Result<Vec<&'static str>> {
    let present: Vec<&str> = JOINT_COLUMNS.iter().copied().filter(|c| find(c).is_some()).collect();
    if !present.is_empty() && present.len() < JOINT_COLUMNS.len() {
        let missing =
            JOINT_COLUMNS.iter().find(|c| !present.contains(c)).copied().unwrap_or_default();
        bail!(
            "{file}:{hl}: missing column \"{missing}\" (a posture-aware set needs all of {})",
            JOINT_COLUMNS.join(",")
        );
    }
    Ok(present)
}

/// A row (line `line`) of `got` fields under a header of `want` is an error.
pub(crate) fn check_row_len(file: &str, line: u64, got: usize, want: usize) -> Result<()> {
    if got != want {
        bail!("{file}:{line}: row has {}, the header has {want}", fields(got));
    }
    Ok(())
}

/// `1 field`, `3 fields`.
fn fields(n: usize) -> String {
    if n == 1 {
        "1 field".into()
    } else {
        format!("{n} fields")
    }
}

pub(crate) fn csv_error(file: &str, e: csv::Error) -> anyhow::Error {
    let line = e.position().map(|p| p.line());
    let what = match e.kind() {
        csv::ErrorKind::Io(io) => format!("cannot read: {io}"),
        csv::ErrorKind::Utf8 { .. } => "not valid UTF-8".to_string(),
        csv::ErrorKind::UnequalLengths { expected_len, len, .. } => {
            format!("row has {}, the header has {expected_len}", fields(*len as usize))
        }
        _ => e.to_string(),
    };
    match line {
        Some(l) => anyhow!("{file}:{l}: {what}"),
        None => anyhow!("{file}: {what}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::output::write_atomically;

    fn read(text: &str, inputs: Inputs, targets: bool) -> Result<Table> {
        read_set_from(Path::new("d.csv"), text.as_bytes(), inputs, targets)
    }

    fn err(text: &str, targets: bool) -> String {
        format!("{:#}", read(text, Inputs::Auto, targets).unwrap_err())
    }

    #[test]
    fn columns_by_name_in_any_order_extra_ignored() {
        let t = read(
            "z, note ,v_r,u_r,x,v_l,u_l,y\r\n65,a,231,284,-3,231,330,-2\r\n\r\n\n85,b,1,2,3,4,5,6\n",
            Inputs::Auto,
            true,
        )
        .unwrap();
        assert_eq!(t.data.n_inputs, 4);
        assert_eq!(t.data.row(0), &[330.0, 231.0, 284.0, 231.0]);
        assert_eq!(t.data.targets[0], [-3.0, -2.0, 65.0]);
        assert_eq!(t.data.row(1), &[5.0, 4.0, 2.0, 1.0]);
        assert_eq!(t.data.targets[1], [3.0, 6.0, 85.0]);
        assert_eq!(t.lines, vec![2, 5]);
        assert_eq!(t.at(1), "d.csv:5");
    }

    #[test]
    fn joint_columns_make_a_nine_input_set() {
        let h = "u_l,v_l,u_r,v_r,neck_pan,neck_tilt,eye_tilt,left_eye_pan,right_eye_pan\n";
        let t = read(&format!("{h}1,2,3,4,5,6,7,8,9\n"), Inputs::Auto, false).unwrap();
        assert_eq!(t.data.n_inputs, 9);
        assert_eq!(t.data.row(0)[8], 9.0);
        let t = read(&format!("{h}1,2,3,4,5,6,7,8,9\n"), Inputs::Stereo, false).unwrap();
        assert_eq!(t.data.n_inputs, 4);
        let e = format!(
            "{:#}",
            read("u_l,v_l,u_r,v_r,neck_pan\n1,2,3,4,5\n", Inputs::Auto, false).unwrap_err()
        );
        assert!(e.contains("missing column \"neck_tilt\""), "{e}");
        let e = format!(
            "{:#}",
            read("u_l,v_l,u_r,v_r\n1,2,3,4\n", Inputs::StereoJoints, false).unwrap_err()
        );
        assert!(e.contains("missing column \"neck_pan\""), "{e}");
    }

    #[test]
    fn every_bad_input_names_file_line_and_column() {
        let h = "u_l,v_l,u_r,v_r,x,y,z\n";
        let ok = "1,2,3,4,5,6,7\n";
        // (file text, ground truth wanted, the whole message).
        let cases: [(String, bool, &str); 13] = [
            (
                format!("{h}{ok}{ok}1,2,3,abc,5,6,7\n"),
                true,
                "d.csv:4: column \"v_r\": \"abc\" is not a number",
            ),
            // Line numbers stay right after blank lines, CRLF endings and quoted fields.
            (
                format!(
                    "{}\r\n\r\n{}\r\n\"1\",2,3,4,5,6,7\r\n\r\n1,2,3,4,5,x,7\r\n",
                    h.trim(),
                    ok.trim()
                ),
                true,
                "d.csv:6: column \"y\": \"x\" is not a number",
            ),
            (
                format!("{h}{ok}1,NaN,3,4,5,6,7\n"),
                true,
                "d.csv:3: column \"v_l\": \"NaN\" is not a finite number",
            ),
            (
                format!("{h}1,2,3,4,5,6,-inf\n"),
                true,
                "d.csv:2: column \"z\": \"-inf\" is not a finite number",
            ),
            (
                format!("{h}1,2,3,4,5,6,1e999\n"),
                true,
                "d.csv:2: column \"z\": \"1e999\" is not a finite number",
            ),
            (format!("{h}{ok}1,2,3,4,5,6\n"), true, "d.csv:3: row has 6 fields, the header has 7"),
            (format!("{h}{ok}1\n"), true, "d.csv:3: row has 1 field, the header has 7"),
            (format!("{h}1,2,,4,5,6,7\n"), true, "d.csv:2: column \"u_r\" is empty"),
            (
                "u_l,v_l,u_r,x,y,z\n1,2,3,5,6,7\n".into(),
                true,
                "d.csv:1: missing column \"v_r\" (the header has: u_l,v_l,u_r,x,y,z)",
            ),
            (
                "u_l,v_l,u_r,v_r\n1,2,3,4\n".into(),
                true,
                "d.csv:1: missing column \"x\" (the header has: u_l,v_l,u_r,v_r)",
            ),
            (h.into(), true, "d.csv: no data rows after the header"),
            (
                "u_l,v_l,u_r,v_r,u_l\n1,2,3,4,5\n".into(),
                false,
                "d.csv:1: column \"u_l\" appears twice in the header",
            ),
            (
                "\n\nu_l,v_l,u_r\n1,2,3\n".into(),
                false,
                "d.csv:3: missing column \"v_r\" (the header has: u_l,v_l,u_r)",
            ),
        ];
        for (text, truth, want) in &cases {
            assert_eq!(err(text, *truth), *want, "{text:?}");
        }
        assert!(err("", false).starts_with("d.csv: empty file"));
        assert!(err("\n\n", false).starts_with("d.csv: empty file"));
        // Ground truth is not needed for inputs-only reads, so a bad `z` does not matter there.
        assert!(read(&format!("{h}1,2,3,4,5,6,oops\n"), Inputs::Stereo, false).is_ok());
    }

    #[test]
    fn atomic_write_leaves_nothing_on_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("out.csv");
        std::fs::write(&p, "old").unwrap();
        let r = write_atomically(&p, |w| {
            w.write_all(b"half")?;
            bail!("boom")
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        write_atomically(&p, |w| Ok(w.write_all(b"new")?)).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[cfg(unix)]
    #[test]
    fn atomic_write_gives_the_mode_of_a_plainly_created_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain.csv");
        std::fs::File::create(&plain).unwrap();
        let p = dir.path().join("atomic.csv");
        write_atomically(&p, |w| Ok(w.write_all(b"x")?)).unwrap();
        let mode = |q: &Path| std::fs::metadata(q).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&p), mode(&plain));
    }
    #[test]
    fn reads_stereo_points_by_header_and_names_bad_fields() {
        let dir = tempfile::tempdir().unwrap();
        let tmp = |name: &str, text: &str| {
            let p = dir.path().join(name);
            std::fs::write(&p, text).unwrap();
            p
        };
        let p = tmp("ok.csv", "x,u_r,v_r,u_l,v_l\n9,289,240,335,240.5\n\n1,1,2,3,4\n");
        let pts = read_stereo_points(&p).unwrap();
        assert_eq!(pts.len(), 2);
        assert_eq!(pts[0], (2, StereoPoint { u_l: 335.0, v_l: 240.5, u_r: 289.0, v_r: 240.0 }));
        assert_eq!(pts[1].0, 4);

        let p = tmp("bad.csv", "u_l,v_l,u_r,v_r\n1,2,3,4\n1,2,abc,4\n");
        let e = format!("{:#}", read_stereo_points(&p).unwrap_err());
        assert!(e.contains("bad.csv:3") && e.contains("u_r") && e.contains("abc"), "{e}");
        let p = tmp("short.csv", "u_l,v_l,u_r,v_r\n1,2,3\n");
        let e = format!("{:#}", read_stereo_points(&p).unwrap_err());
        assert!(e.contains("short.csv:2"), "{e}");
        let p = tmp("hdr.csv", "u_l,v_l,u_r\n1,2,3\n");
        let e = format!("{:#}", read_stereo_points(&p).unwrap_err());
        assert!(e.contains("hdr.csv:1") && e.contains("v_r"), "{e}");
    }
}
