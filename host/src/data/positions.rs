//! `POSITIONS.csv`: where the user puts the board for `hvs collect`, one placement per row.
//!
//! Columns by name, any order: `x,y,z` (the board centre in the head frame, cm; the board
//! upright and facing the head, as `hvs board detect` assumes). Other columns are refused (a
//! misspelt `z` must not pass silently). Errors name the file, the line and the column.

use super::csv::{
    check_row_len, check_unique_names, csv_error, csv_reader, missing_column, number, LineCounter,
};
use anyhow::{bail, Context, Result};
use std::path::Path;

/// Most placements one file may give.
pub const MAX_PLACEMENTS: usize = 10_000;

/// One board placement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// 1-based line of the row.
    pub line: u64,
    /// Board centre `[x, y, z]` (cm, head frame).
    pub xyz: [f64; 3],
}

/// Reads `path`.
pub fn read(path: &Path) -> Result<Vec<Placement>> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).with_context(|| format!("{file}: cannot read"))?;
    parse(&file, &bytes)
}

/// Parses the text of a positions file named `file` (for messages).
pub fn parse(file: &str, bytes: &[u8]) -> Result<Vec<Placement>> {
    let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
    let mut lines_of = LineCounter::new(bytes);
    let mut rdr = csv_reader(bytes);
    let header = rdr.headers().map_err(|e| csv_error(file, e))?.clone();
    let hl = lines_of.line_at(header.position().map_or(0, |p| p.byte()));
    let names: Vec<String> = header.iter().map(str::to_string).collect();
    if names.iter().all(String::is_empty) {
        bail!("{file}: empty file (expected a header row naming the columns x,y,z)");
    }
    if names.iter().all(|n| n.trim().parse::<f64>().is_ok()) {
        bail!(
            "{file}:{hl}: the first line must be the header naming the columns x,y,z, but it holds numbers ({})",
            names.join(",")
        );
    }
    check_unique_names(file, hl, &names, false)?;
    if let Some((k, n)) =
        names.iter().enumerate().find(|(_, n)| !["x", "y", "z"].contains(&n.as_str()))
    {
        bail!("{file}:{hl}: column {} \"{n}\": a positions file has the columns x,y,z only", k + 1);
    }
    let find = |c: &str| {
        names.iter().position(|n| n == c).ok_or_else(|| missing_column(file, hl, c, &names))
    };
    let idx = [find("x")?, find("y")?, find("z")?];
    let mut out = Vec::new();
    let mut rec = csv::StringRecord::new();
    while rdr.read_record(&mut rec).map_err(|e| csv_error(file, e))? {
        let line = lines_of.line_at(rec.position().map_or(0, |p| p.byte()));
        check_row_len(file, line, rec.len(), header.len())?;
        let mut xyz = [0.0; 3];
        for (k, col) in ["x", "y", "z"].iter().enumerate() {
            xyz[k] = number(file, line, col, rec[idx[k]].as_bytes())?;
            let most = crate::data::validate::MAX_ABS_CM;
            if xyz[k].abs() > most {
                bail!(
                    "{file}:{line}: column \"{col}\": {} cm is not a place a head's cameras see (|{col}| must be at most {most} cm, as in a training set)",
                    xyz[k]
                );
            }
        }
        if xyz[2] <= 0.0 {
            bail!(
                "{file}:{line}: column \"z\": {} cm is not a depth in front of the head (must be > 0)",
                xyz[2]
            );
        }
        if out.len() == MAX_PLACEMENTS {
            bail!("{file}:{line}: more than {MAX_PLACEMENTS} placements");
        }
        out.push(Placement { line, xyz });
    }
    if out.is_empty() {
        bail!("{file}: no placements after the header");
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        format!("{:#}", parse("P.csv", text.as_bytes()).unwrap_err())
    }

    #[test]
    fn reads_columns_in_any_order() {
        let p = parse("P.csv", b"z,x,y\n65,1,-2\n85,0,0\n").unwrap();
        assert_eq!(p.len(), 2);
        assert_eq!(p[0].xyz, [1.0, -2.0, 65.0]);
        assert_eq!((p[1].line, p[1].xyz), (3, [0.0, 0.0, 85.0]));
    }

    #[test]
    fn bad_rows_name_file_line_and_column() {
        assert!(err("x,y\n0,0\n").contains("missing column \"z\""));
        assert!(err("x,y,zz\n0,0,1\n").contains("P.csv:1: column 3 \"zz\""));
        let e = err("x,y,z\n0,0,65\n0,nan,85\n");
        assert!(e.contains("P.csv:3") && e.contains("\"y\""), "{e}");
        let e = err("x,y,z\n0,0,1e30\n");
        assert!(e.contains("P.csv:2") && e.contains("\"z\"") && e.contains("at most"), "{e}");
        let e = err("x,y,z\n0,0,-5\n");
        assert!(e.contains("P.csv:2") && e.contains("\"z\""), "{e}");
        assert!(err("x,y,z\n").contains("no placements"));
        assert!(err("").contains("empty file"));
        // A file without its header: its first row is not taken for column names.
        let e = err("0,0,85\n1,2,95\n");
        assert!(e.contains("P.csv:1") && e.contains("header") && e.contains("0,0,85"), "{e}");
        let e = err("x,y,z\n0,0\n");
        assert!(e.contains("P.csv:2"), "{e}");
    }
}
