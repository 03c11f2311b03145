//! `hvs head`: talk to a head controller (real, over a serial port, or QEMU's over TCP).
//!
//! Subcommands: `ping`, `info`, `estimate --points FILE.csv` (prints
//! `u_l,v_l,u_r,v_r,x,y,z,source,in_range`, floats in shortest round-trip form so the bits can
//! be compared with host inference), `look U_L V_L U_R V_R`, `home`, `bench`.

use crate::link::{Endpoint, Link};
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use hvs_shared::protocol::{
    ErrorCode, EstimateData, InfoData, Mode, RequestBody, ResponseBody, SlotStatus, Source,
    StereoPoint,
};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Arguments of `hvs head`.
#[derive(Debug, Clone, Args)]
pub struct HeadArgs {
    /// The head over TCP: `tcp:HOST:PORT` (for `hvs emulate`), or `serial:PATH[@BAUD]`.
    #[arg(long, conflicts_with = "port", required_unless_present = "port")]
    pub connect: Option<String>,
    /// The head on a serial port (`/dev/ttyUSB0`, `COM3`).
    #[arg(long)]
    pub port: Option<String>,
    /// Serial baud rate.
    #[arg(long, default_value_t = hvs_shared::protocol::BAUD_RATE)]
    pub baud: u32,
    /// Milliseconds to wait for each response (and for the head to come up).
    #[arg(long, default_value_t = 3000)]
    pub timeout_ms: u64,
    /// What to ask.
    #[command(subcommand)]
    pub command: HeadCommand,
}

/// `hvs head` subcommands.
#[derive(Debug, Clone, Subcommand)]
pub enum HeadCommand {
    /// Check that the head answers.
    Ping,
    /// Firmware version, running slot and generation, mode, model metadata, slot states.
    Info,
    /// Depth estimates of every row of a CSV with columns u_l,v_l,u_r,v_r (others ignored).
    /// Rows the head has no estimate for keep empty x,y,z and source `none` (with a warning).
    Estimate {
        /// Input CSV.
        #[arg(long)]
        points: PathBuf,
        /// Output CSV (default: standard output).
        #[arg(long, short)]
        output: Option<PathBuf>,
    },
    /// Estimate a point and move the head to fixate it.
    Look {
        /// Left image column (px).
        #[arg(allow_negative_numbers = true)]
        u_l: f32,
        /// Left image row (px).
        #[arg(allow_negative_numbers = true)]
        v_l: f32,
        /// Right image column (px).
        #[arg(allow_negative_numbers = true)]
        u_r: f32,
        /// Right image row (px).
        #[arg(allow_negative_numbers = true)]
        v_r: f32,
    },
    /// Move every axis to its home position.
    Home,
    /// Instructions per inference (firmware built with `--features bench`, under QEMU with
    /// `-icount shift=0`).
    Bench {
        /// Inferences to time (the head caps it at 2000).
        #[arg(long, default_value_t = 1000)]
        count: u32,
    },
}

impl HeadArgs {
    /// The endpoint named by `--connect` or `--port`/`--baud`.
    pub fn endpoint(&self) -> Result<Endpoint> {
        match (&self.connect, &self.port) {
            (Some(c), _) => c.parse(),
            (None, Some(p)) => Ok(Endpoint::Serial {
                path: p.clone(),
                baud: self.baud,
            }),
            (None, None) => bail!("give --connect tcp:HOST:PORT or --port DEVICE"),
        }
    }
}

/// Opens a link and waits until the head answers.
pub fn connect(endpoint: &Endpoint, timeout: Duration) -> Result<Link> {
    let mut link = Link::open(endpoint, timeout)?;
    link.timeout = timeout;
    link.wait_ready(timeout)?;
    Ok(link)
}

/// `hvs head`.
pub fn run(args: &HeadArgs) -> Result<()> {
    let timeout = Duration::from_millis(args.timeout_ms);
    let mut link = connect(&args.endpoint()?, timeout)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    match &args.command {
        HeadCommand::Ping => {
            expect(link.request(RequestBody::Ping)?, "Ping", |b| {
                matches!(b, ResponseBody::Pong).then_some(())
            })?;
            writeln!(out, "pong from {}", link.endpoint())?;
        }
        HeadCommand::Info => {
            let info = expect(link.request(RequestBody::Info)?, "Info", |b| match b {
                ResponseBody::Info(i) => Some(i),
                _ => None,
            })?;
            write_info(&mut out, &info)?;
        }
        HeadCommand::Estimate { points, output } => {
            let pts = read_points(points)?;
            let mut csv = String::from("u_l,v_l,u_r,v_r,x,y,z,source,in_range\n");
            for (line, p) in &pts {
                match link.request(RequestBody::Estimate(*p))? {
                    ResponseBody::Estimate(e) => csv.push_str(&estimate_row(p, &e)),
                    // A point without an estimate keeps its row, with empty coordinates.
                    ResponseBody::Error(code) => {
                        eprintln!(
                            "warning: {}:{line}: no estimate: {}",
                            points.display(),
                            error_text(code)
                        );
                        csv.push_str(&format!(
                            "{},{},{},{},,,,none,false\n",
                            p.u_l, p.v_l, p.u_r, p.v_r
                        ));
                    }
                    other => bail!(
                        "{}:{line}: head answered Estimate with an unexpected {other:?}",
                        points.display()
                    ),
                }
            }
            match output {
                Some(path) => write_atomic(path, csv.as_bytes())?,
                None => out.write_all(csv.as_bytes())?,
            }
        }
        HeadCommand::Look { u_l, v_l, u_r, v_r } => {
            let p = StereoPoint {
                u_l: *u_l,
                v_l: *v_l,
                u_r: *u_r,
                v_r: *v_r,
            };
            let l = expect(link.request(RequestBody::Look(p))?, "Look", |b| match b {
                ResponseBody::Look(l) => Some(l),
                _ => None,
            })?;
            let t = l.target.0;
            writeln!(
                out,
                "target x={} y={} z={} cm ({:?}, in_range={})",
                l.estimate.x, l.estimate.y, l.estimate.z, l.estimate.source, l.estimate.in_range
            )?;
            writeln!(
                out,
                "joints deg: neck_pan={} neck_tilt={} eye_tilt={} left_eye_pan={} right_eye_pan={}{}",
                t[0],
                t[1],
                t[2],
                t[3],
                t[4],
                if l.limited { " (limited)" } else { "" }
            )?;
        }
        HeadCommand::Home => {
            expect(link.request(RequestBody::Home)?, "Home", |b| {
                matches!(b, ResponseBody::Home).then_some(())
            })?;
            writeln!(out, "homing")?;
        }
        HeadCommand::Bench { count } => {
            let p = StereoPoint {
                u_l: 330.0,
                v_l: 241.0,
                u_r: 300.0,
                v_r: 239.0,
            };
            let b = expect(
                link.request(RequestBody::Bench {
                    point: p,
                    count: *count,
                })?,
                "Bench",
                |b| match b {
                    ResponseBody::Bench(d) => Some(d),
                    _ => None,
                },
            )?;
            let per = b.ticks as f64 / b.count as f64;
            writeln!(
                out,
                "count={} ticks={} overhead_ticks={} tick_hz={} ticks_per_inference={per:.2} instructions_per_inference_icount0={:.1}",
                b.count,
                b.ticks,
                b.overhead_ticks,
                b.tick_hz,
                per * 1e9 / b.tick_hz as f64
            )?;
        }
    }
    Ok(())
}

/// One estimate through the link; head errors become messages.
pub fn estimate(link: &mut Link, p: &StereoPoint) -> Result<EstimateData> {
    expect(
        link.request(RequestBody::Estimate(*p))?,
        "Estimate",
        |b| match b {
            ResponseBody::Estimate(e) => Some(e),
            _ => None,
        },
    )
}

fn expect<T>(
    body: ResponseBody,
    what: &str,
    pick: impl FnOnce(ResponseBody) -> Option<T>,
) -> Result<T> {
    if let ResponseBody::Error(code) = body {
        bail!("head answered {what} with error: {}", error_text(code));
    }
    match pick(body) {
        Some(t) => Ok(t),
        None => bail!("head answered {what} with an unexpected {body:?}"),
    }
}

/// A user-facing sentence for an error code.
pub fn error_text(code: ErrorCode) -> &'static str {
    match code {
        ErrorCode::Malformed => "malformed frame",
        ErrorCode::Oversize => "frame too long",
        ErrorCode::NonFinite => "a coordinate is NaN or infinite",
        ErrorCode::Unreachable => "the point cannot be fixated (behind the cameras or too close)",
        ErrorCode::NoSolution => {
            "no depth for this point (zero/negative disparity or non-finite result)"
        }
        ErrorCode::Unsupported => "not supported by this firmware",
    }
}

/// The CSV row of one estimate (shortest round-trip floats).
pub fn estimate_row(p: &StereoPoint, e: &EstimateData) -> String {
    let source = match e.source {
        Source::Network => "network",
        Source::Fallback => "fallback",
    };
    format!(
        "{},{},{},{},{},{},{},{source},{}\n",
        p.u_l, p.v_l, p.u_r, p.v_r, e.x, e.y, e.z, e.in_range
    )
}

fn write_info(out: &mut impl Write, i: &InfoData) -> Result<()> {
    let f = i.firmware;
    writeln!(
        out,
        "firmware: {}.{}.{} (protocol {})",
        f.major, f.minor, f.patch, i.protocol
    )?;
    writeln!(
        out,
        "mode: {}",
        match i.mode {
            Mode::Network => "network",
            Mode::Fallback => "fallback (traditional method, built-in calibration)",
        }
    )?;
    match i.slot {
        Some(s) => writeln!(out, "slot: {s:?}, generation {}", i.generation)?,
        None => writeln!(out, "slot: none")?,
    }
    for (name, s) in [("A", i.slot_a), ("B", i.slot_b)] {
        let text = match s {
            SlotStatus::Empty => "empty".to_string(),
            SlotStatus::Invalid(e) => format!("invalid ({e})"),
            SlotStatus::UnsupportedTopology {
                inputs,
                hidden,
                outputs,
            } => format!(
                "valid but {inputs}-{hidden}-{outputs} is not a topology this firmware runs"
            ),
            SlotStatus::Valid { generation } => format!("valid, generation {generation}"),
        };
        writeln!(out, "slot {name}: {text}")?;
    }
    if let Some(m) = i.model {
        writeln!(
            out,
            "model: {}-{}-{}, seed {}, train hash {:016x}, {} training points, training error {}%",
            m.inputs, m.hidden, m.outputs, m.seed, m.train_hash, m.train_points, m.train_error_pct
        )?;
    }
    writeln!(
        out,
        "fallback calibration: phi {} px, d {} cm, principal point ({}, {})",
        i.fallback.phi, i.fallback.half_baseline, i.fallback.u0, i.fallback.v0
    )?;
    if let Some(peak) = i.stack_peak {
        writeln!(out, "stack peak: {peak} B")?;
    }
    Ok(())
}

/// Reads the `u_l,v_l,u_r,v_r` columns of a CSV (by header name), with 1-based line numbers.
/// Values are parsed as f64 and rounded to f32, as host inference does.
pub fn read_points(path: &Path) -> Result<Vec<(usize, StereoPoint)>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((_, header)) = lines.next() else {
        bail!(
            "{}: empty file (expected a header u_l,v_l,u_r,v_r)",
            path.display()
        );
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let mut idx = [0usize; 4];
    for (k, want) in ["u_l", "v_l", "u_r", "v_r"].iter().enumerate() {
        idx[k] = names
            .iter()
            .position(|n| n == want)
            .with_context(|| format!("{}:1: missing column {want:?} in header", path.display()))?;
    }
    let mut pts = Vec::new();
    for (i, line) in lines {
        let lineno = i + 1;
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let mut v = [0f32; 4];
        for (k, &j) in idx.iter().enumerate() {
            let name = names[j];
            let s = fields
                .get(j)
                .with_context(|| format!("{}:{lineno}: missing field {name:?}", path.display()))?;
            let x: f64 = s.parse().with_context(|| {
                format!(
                    "{}:{lineno}: field {name:?}: {s:?} is not a number",
                    path.display()
                )
            })?;
            v[k] = x as f32;
        }
        pts.push((
            lineno,
            StereoPoint {
                u_l: v[0],
                v_l: v[1],
                u_r: v[2],
                v_r: v[3],
            },
        ));
    }
    Ok(pts)
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
    let name = path
        .file_name()
        .with_context(|| format!("{}: not a file path", path.display()))?;
    let tmp = dir.unwrap_or(Path::new(".")).join(format!(
        ".{}.tmp{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    std::fs::write(&tmp, bytes).with_context(|| format!("{}: cannot write", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("{}: cannot write", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str, text: &str) -> PathBuf {
        let p = std::env::temp_dir().join(format!("hvs-head-{}-{name}", std::process::id()));
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn reads_points_by_header_and_names_bad_fields() {
        let p = tmp(
            "ok.csv",
            "x,u_r,v_r,u_l,v_l\n9,289,240,335,240.5\n\n1,1,2,3,4\n",
        );
        let pts = read_points(&p).unwrap();
        assert_eq!(pts.len(), 2);
        assert_eq!(
            pts[0],
            (
                2,
                StereoPoint {
                    u_l: 335.0,
                    v_l: 240.5,
                    u_r: 289.0,
                    v_r: 240.0
                }
            )
        );
        assert_eq!(pts[1].0, 4);

        let p = tmp("bad.csv", "u_l,v_l,u_r,v_r\n1,2,3,4\n1,2,abc,4\n");
        let e = format!("{:#}", read_points(&p).unwrap_err());
        assert!(
            e.contains("bad.csv:3") && e.contains("u_r") && e.contains("abc"),
            "{e}"
        );
        let p = tmp("short.csv", "u_l,v_l,u_r,v_r\n1,2,3\n");
        let e = format!("{:#}", read_points(&p).unwrap_err());
        assert!(e.contains("short.csv:2") && e.contains("v_r"), "{e}");
        let p = tmp("hdr.csv", "u_l,v_l,u_r\n1,2,3\n");
        let e = format!("{:#}", read_points(&p).unwrap_err());
        assert!(e.contains("hdr.csv:1") && e.contains("v_r"), "{e}");
    }

    #[test]
    fn estimate_rows_round_trip_floats_exactly() {
        let p = StereoPoint {
            u_l: 335.0,
            v_l: 240.0,
            u_r: 289.0,
            v_r: 240.0,
        };
        let e = EstimateData {
            x: -1.749_999_9,
            y: 1e-7,
            z: 65.000_01,
            source: Source::Network,
            in_range: true,
        };
        let row = estimate_row(&p, &e);
        let f: Vec<&str> = row.trim().split(',').collect();
        assert_eq!(f[4].parse::<f32>().unwrap().to_bits(), e.x.to_bits());
        assert_eq!(f[5].parse::<f32>().unwrap().to_bits(), e.y.to_bits());
        assert_eq!(f[6].parse::<f32>().unwrap().to_bits(), e.z.to_bits());
        assert_eq!(&f[7..], ["network", "true"]);
    }

    #[test]
    fn endpoint_from_flags() {
        let a = HeadArgs {
            connect: None,
            port: Some("/dev/ttyACM0".into()),
            baud: 9600,
            timeout_ms: 1,
            command: HeadCommand::Ping,
        };
        assert_eq!(
            a.endpoint().unwrap(),
            Endpoint::Serial {
                path: "/dev/ttyACM0".into(),
                baud: 9600
            }
        );
    }
}
