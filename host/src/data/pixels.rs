//! `PIXELS.csv`: left-image pixels to locate (`u_l,v_l`, other columns passed through), as
//! `hvs locate --points` reads them.

use crate::data::csv::{
    check_row_len, check_unique_names, csv_error, csv_reader, missing_column, number, LineCounter,
};
use anyhow::{bail, Context, Result};
use std::path::Path;

/// The pixels of a `PIXELS.csv` (`u_l,v_l`, finite numbers),
/// with the header and each row's other fields for the output.
#[derive(Debug)]
pub struct Pixels {
    /// Names of the passed-through columns.
    pub extra_names: Vec<String>,
    /// `(u_l, v_l)` per row.
    pub points: Vec<[f64; 2]>,
    /// The passed-through fields per row.
    pub extra: Vec<Vec<String>>,
    /// Input columns of names the output writes itself ([`WRITTEN`]): replaced, not passed
    /// through.
    pub replaced: Vec<String>,
}

/// The columns `hvs locate` writes after `u_l,v_l` (its header; `Located::csv_row` in this
/// order): an input column of one of these names is replaced by the located values (and
/// `hvs locate` says so).
pub const WRITTEN: [&str; 7] = ["u_r", "v_r", "x", "y", "z", "score", "status"];

/// Reads `path`; errors name the file, the line and the column.
pub fn read_pixels(path: &Path) -> Result<Pixels> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).with_context(|| format!("{file}: cannot read"))?;
    let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(&bytes);
    let mut lines_of = LineCounter::new(bytes);
    let mut rdr = csv_reader(bytes);
    let header = rdr.headers().map_err(|e| csv_error(&file, e))?.clone();
    let hl = lines_of.line_at(header.position().map_or(0, |p| p.byte()));
    let names: Vec<String> = header.iter().map(str::to_string).collect();
    check_unique_names(&file, hl, &names, false)?;
    let find = |c: &str| {
        let at = names.iter().position(|n| n == c);
        at.ok_or_else(|| missing_column(&file, hl, c, &names))
    };
    let (ui, vi) = (find("u_l")?, find("v_l")?);
    // A column of a name the output gives its own values is replaced by them: said, not
    // passed through (it would be doubled).
    let replaced: Vec<&str> =
        names.iter().map(String::as_str).filter(|n| WRITTEN.contains(n)).collect();
    let extra_idx: Vec<usize> = (0..names.len())
        .filter(|&k| k != ui && k != vi && !WRITTEN.contains(&names[k].as_str()))
        .collect();
    let mut out = Pixels {
        extra_names: extra_idx.iter().map(|&k| names[k].clone()).collect(),
        points: Vec::new(),
        extra: Vec::new(),
        replaced: replaced.iter().map(|n| n.to_string()).collect(),
    };
    let mut rec = csv::StringRecord::new();
    while rdr.read_record(&mut rec).map_err(|e| csv_error(&file, e))? {
        let line = lines_of.line_at(rec.position().map_or(0, |p| p.byte()));
        check_row_len(&file, line, rec.len(), header.len())?;
        // One rule with every CSV input (`data::csv`'s numbers): an empty field, text, NaN
        // and infinities are refused, each saying which.
        let num = |k: usize, c: &str| number(&file, line, c, rec[k].as_bytes());
        out.points.push([num(ui, "u_l")?, num(vi, "v_l")?]);
        out.extra.push(extra_idx.iter().map(|&k| rec[k].to_string()).collect());
    }
    if out.points.is_empty() {
        bail!("{file}: no points after the header");
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every way a `PIXELS.csv` can be wrong is one line naming the file (and the line and
    /// column where there is one).
    #[test]
    fn bad_pixel_files_name_file_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("px.csv");
        let err = |text: &str| {
            std::fs::write(&path, text).unwrap();
            let e = format!("{:#}", read_pixels(&path).unwrap_err());
            assert!(!e.contains('\n'), "{e}");
            e.strip_prefix(&format!("{}", path.display())).map(str::to_string).unwrap_or(e)
        };
        assert_eq!(err(""), ": empty file (expected a header row naming the column \"u_l\")");
        assert_eq!(err("u_l,v_l\n"), ": no points after the header");
        assert_eq!(err("u_l,v_l\n1,2\n3\n"), ":3: row has 1 field, the header has 2");
        assert_eq!(err("u_l,v_l\nx,2\n"), ":2: column \"u_l\": \"x\" is not a number");
        assert_eq!(err("u_l,v_l\nNaN,2\n"), ":2: column \"u_l\": \"NaN\" is not a finite number");
        assert_eq!(err("u_l,v_l\n1,\n"), ":2: column \"v_l\" is empty");
        assert_eq!(err("u,v\n1,2\n"), ":1: missing column \"u_l\" (the header has: u,v)");
        std::fs::write(&path, "tag,z,u_l,v_l,u_r\nq,2,3,4,5\n").unwrap();
        let p = read_pixels(&path).unwrap();
        assert_eq!(
            (p.points, p.extra_names, p.extra),
            (vec![[3.0, 4.0]], vec!["tag".to_string()], vec![vec!["q".to_string()]])
        );
        assert_eq!(p.replaced, ["z", "u_r"]);
        let ok = read_pixels(&{
            std::fs::write(&path, "u_l,v_l,tag\n1,2.5,a\n").unwrap();
            path.clone()
        })
        .unwrap();
        assert_eq!(
            (ok.points, ok.extra, ok.extra_names),
            (vec![[1.0, 2.5]], vec![vec!["a".to_string()]], vec!["tag".to_string()])
        );
    }
}
