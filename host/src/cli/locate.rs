//! `hvs locate`: points of the left image found in the right one and turned into X, Y, Z by the
//! model, with nothing but the model and the two images ([`crate::depth::locate()`]).

use super::StereoArgs;
use crate::data::csv::{
    check_row_len, check_unique_names, csv_error, csv_reader, missing_column, LineCounter,
};
use crate::data::output::{check_outputs, write_bytes, write_output};
use crate::depth::{locate_files, LocatedFiles};
use crate::vision::{locate_overlay, png_bytes, Located};
use anyhow::{anyhow, bail, Context, Result};
use std::path::{Path, PathBuf};

/// Arguments of `hvs locate`.
#[derive(Debug, clap::Args)]
#[command(
    about = "Find left-image points in the right image and give their X, Y, Z",
    long_about = "Find points of the left image in the right one and give the model's X, Y, Z \
    of each trustworthy match. The points are answered from the dense matches of the pair, \
    those of `hvs depth` (census and semi-global matching along the model's epipolar lines, \
    inside the disparities its depth box allows, with uniqueness, left-right and speckle \
    checks, sub-pixel), interpolated between pixels. The model carries the geometry the search \
    needs, learned from its training pixels (`hvs train` stores it); no camera parameter is \
    used. A point without a trustworthy match keeps u_r..z empty and says why in `status`: \
    outside, nan_input, no_match, out_of_depth_range, no_estimate; `score` is the match's \
    confidence (0..1). A Z-only model gives z and leaves x, y empty."
)]
pub struct Args {
    #[command(flatten)]
    pub pair: StereoArgs,
    /// Points to locate: a CSV with columns u_l,v_l (other columns passed through).
    #[arg(long, value_name = "PIXELS.csv", conflicts_with = "at", required_unless_present = "at")]
    pub points: Option<PathBuf>,
    /// One point U,V of the left image, printed.
    #[arg(long, value_name = "U,V", allow_hyphen_values = true)]
    pub at: Option<String>,
    /// Output CSV: u_l,v_l,u_r,v_r,x,y,z,score,status then the passed-through columns
    /// (default: standard output). Not with --at, which prints its one point.
    #[arg(short = 'o', long, value_name = "OUT.csv", conflicts_with = "at")]
    pub output: Option<PathBuf>,
    /// The two images side by side with each match drawn and labelled by its row number.
    #[arg(long, value_name = "OUT.png")]
    pub overlay: Option<PathBuf>,
}

/// The pixels of a `PIXELS.csv` (`u_l,v_l`, `NaN` allowed: it gets the status `nan_input`),
/// with the header and each row's other fields for the output.
#[derive(Debug)]
pub struct Pixels {
    /// Names of the passed-through columns.
    pub extra_names: Vec<String>,
    /// `(u_l, v_l)` per row.
    pub points: Vec<[f64; 2]>,
    /// The passed-through fields per row.
    pub extra: Vec<Vec<String>>,
}

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
    let own = ["u_l", "v_l", "u_r", "v_r", "x", "y", "z", "score", "status"];
    let extra_idx: Vec<usize> =
        (0..names.len()).filter(|&k| !own.contains(&names[k].as_str())).collect();
    let mut out = Pixels {
        extra_names: extra_idx.iter().map(|&k| names[k].clone()).collect(),
        points: Vec::new(),
        extra: Vec::new(),
    };
    let mut rec = csv::StringRecord::new();
    while rdr.read_record(&mut rec).map_err(|e| csv_error(&file, e))? {
        let line = lines_of.line_at(rec.position().map_or(0, |p| p.byte()));
        check_row_len(&file, line, rec.len(), header.len())?;
        let num = |k: usize, c: &str| -> Result<f64> {
            let t = &rec[k];
            // One rule with every CSV input: NaN and infinities are refused alike.
            t.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| {
                anyhow!("{file}:{line}: column \"{c}\": {t:?} is not a finite number")
            })
        };
        out.points.push([num(ui, "u_l")?, num(vi, "v_l")?]);
        out.extra.push(extra_idx.iter().map(|&k| rec[k].to_string()).collect());
    }
    if out.points.is_empty() {
        bail!("{file}: no points after the header");
    }
    Ok(out)
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map_or_else(String::new, |v| v.to_string())
}

/// One output row (without the passed-through fields).
pub fn row(l: &Located) -> String {
    let r = l.right;
    let x = l.xyz;
    format!(
        "{},{},{},{},{},{},{},{},{}",
        l.left[0],
        l.left[1],
        opt(r.map(|r| r[0] as f32)),
        opt(r.map(|r| r[1] as f32)),
        opt(x.map(|x| x[0]).filter(|v| v.is_finite())),
        opt(x.map(|x| x[1]).filter(|v| v.is_finite())),
        opt(x.map(|x| x[2])),
        if l.score.is_finite() { format!("{:.4}", l.score) } else { String::new() },
        l.status
    )
}

/// `hvs locate`.
pub fn run(a: Args) -> Result<()> {
    let mut inputs: Vec<(&str, &Path)> = a.pair.inputs().to_vec();
    if let Some(p) = &a.points {
        inputs.push(("--points", p));
    }
    let mut outputs: Vec<(&str, &Path)> = Vec::new();
    if let Some(o) = &a.output {
        outputs.push(("-o", o));
    }
    if let Some(o) = &a.overlay {
        outputs.push(("--overlay", o));
    }
    check_outputs(&outputs, &inputs)?;
    let pixels = match (&a.points, &a.at) {
        (Some(p), _) => read_pixels(p)?,
        (None, Some(at)) => Pixels {
            extra_names: Vec::new(),
            points: vec![crate::cli::parse_at(at)?],
            extra: vec![Vec::new()],
        },
        (None, None) => bail!("give --points PIXELS.csv or --at U,V"),
    };
    // The one point asked for with --at must lie in the image (its header says; a file that
    // cannot be read is left to the full read below, which names the problem).
    if let (Some(_), Ok((w, h))) = (&a.at, image::image_dimensions(&a.pair.left)) {
        let [u, v] = pixels.points[0];
        if !crate::depth::inside_image(u, v, (w, h)) {
            bail!("--at {u},{v}: outside the {w}x{h} left image {}", a.pair.left.display());
        }
    }
    let LocatedFiles { found, warnings, left: l, right: r } =
        locate_files(&a.pair.model, &a.pair.left, &a.pair.right, &pixels.points)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    if let Some(p) = &a.overlay {
        write_bytes(p, &png_bytes(&locate_overlay(&l, &r, &found))?)?;
    }
    if a.points.is_none() {
        let text = found[0].line();
        return crate::cli::say(format_args!("{text}"));
    }
    let mut header = String::from("u_l,v_l,u_r,v_r,x,y,z,score,status");
    for n in &pixels.extra_names {
        header.push(',');
        header.push_str(n);
    }
    write_output(a.output.as_deref(), |w| {
        writeln!(w, "{header}")?;
        for (l, extra) in found.iter().zip(&pixels.extra) {
            write!(w, "{}", row(l))?;
            for e in extra {
                write!(w, ",{e}")?;
            }
            writeln!(w)?;
        }
        Ok(())
    })?;
    let ok = found.iter().filter(|f| f.status == "ok").count();
    eprintln!("{ok} of {} points located", found.len());
    Ok(())
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
        assert_eq!(err("u_l,v_l\nx,2\n"), ":2: column \"u_l\": \"x\" is not a finite number");
        assert_eq!(err("u,v\n1,2\n"), ":1: missing column \"u_l\" (the header has: u,v)");
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
