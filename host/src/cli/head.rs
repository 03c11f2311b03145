//! `hvs head`: requests to a head controller (real, over a serial port, or QEMU's over TCP).
//!
//! Subcommands: `ping`, `info`, `estimate --points FILE.csv` (prints
//! `u_l,v_l,u_r,v_r,x,y,z,source,in_range`, floats in shortest round-trip form so the bits can
//! be compared with host inference), `look U_L V_L U_R V_R`, `home`, `posture A,B,C,D,E`,
//! `state`, `bench`.

use crate::data::csv::read_stereo_points;
use crate::data::output::check_not_input;
use crate::data::output::write_bytes;
use crate::device::client::{
    self, connect, error_text, estimate_row, expect, no_estimate_row, write_info, ESTIMATE_HEADER,
};
use crate::device::link::Endpoint;
use anyhow::{bail, Context, Result};
use hvs_shared::runtime::protocol::{Joints, RequestBody, ResponseBody, StateData, StereoPoint};
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `hvs head`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// The head over TCP: `tcp:HOST:PORT` (for `hvs emulate`), or `serial:PATH[@BAUD]`.
    #[arg(long, conflicts_with = "port")]
    pub connect: Option<String>,
    /// The head on a serial port (`/dev/ttyUSB0`, `COM3`; at --baud), or, as `hvs track` and
    /// `hvs view` take it, `serial:PATH[@BAUD]` or `tcp:HOST:PORT`.
    #[arg(long)]
    pub port: Option<String>,
    /// Serial baud rate.
    #[arg(long, default_value_t = hvs_shared::runtime::protocol::BAUD_RATE, allow_negative_numbers = true, value_parser = crate::cli::whole_u32)]
    pub baud: u32,
    /// Milliseconds to wait for each response (and for the head to come up).
    #[arg(long, default_value_t = 3000, allow_negative_numbers = true, value_parser = crate::cli::whole_u64)]
    pub timeout_ms: u64,
    /// What to ask.
    #[command(subcommand)]
    pub command: HeadCommand,
}

/// `hvs head` subcommands.
#[derive(Debug, Clone, clap::Subcommand)]
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
    /// The pair is given as U_L V_L U_R V_R, or found from images: `--model M.hvsw --left L.png
    /// --right R.png --at U,V` locates left pixel U,V in the right image as `hvs locate` does
    /// and sends the matched pair.
    Look {
        /// Left image column (px).
        #[arg(allow_negative_numbers = true, required_unless_present_any = ["at", "model"])]
        u_l: Option<f32>,
        /// Left image row (px).
        #[arg(allow_negative_numbers = true, required_unless_present_any = ["at", "model"])]
        v_l: Option<f32>,
        /// Right image column (px).
        #[arg(allow_negative_numbers = true, required_unless_present_any = ["at", "model"])]
        u_r: Option<f32>,
        /// Right image row (px).
        #[arg(allow_negative_numbers = true, required_unless_present_any = ["at", "model"])]
        v_r: Option<f32>,
        /// The model the head runs (its matcher geometry finds the point in the right image).
        #[arg(long, value_name = "M.hvsw", requires_all = ["left", "right", "at"])]
        model: Option<PathBuf>,
        /// The left image.
        #[arg(long, value_name = "L.png", requires = "model")]
        left: Option<PathBuf>,
        /// The right image.
        #[arg(long, value_name = "R.png", requires = "model")]
        right: Option<PathBuf>,
        /// The left pixel U,V to look at.
        #[arg(long, value_name = "U,V", allow_hyphen_values = true, requires = "model", conflicts_with_all = ["u_l", "v_l", "u_r", "v_r"])]
        at: Option<String>,
    },
    /// Move every axis to its home position.
    Home,
    /// Move the head to these joint angles (degrees, in the order neck_pan, neck_tilt,
    /// eye_tilt, left_eye_pan, right_eye_pan; each clamped to its limits by the head; `nan`
    /// keeps that axis' goal). Prints the state the head answers with. Protocol 3.
    Posture {
        /// Five angles, NECK_PAN,NECK_TILT,EYE_TILT,LEFT_EYE_PAN,RIGHT_EYE_PAN (degrees).
        #[arg(allow_hyphen_values = true, value_name = "A,B,C,D,E")]
        joints: String,
    },
    /// Where the head is: its joints, the current move's goal, its clock. Protocol 3.
    State,
    /// Instructions per inference (firmware built with `--features bench`, under QEMU with
    /// `-icount shift=0`).
    Bench {
        /// Inferences to time (the head caps it at 2000).
        #[arg(long, default_value_t = 1000, allow_negative_numbers = true, value_parser = crate::cli::whole_u32)]
        count: u32,
    },
}

impl Args {
    /// The endpoint named by `--connect` or `--port`/`--baud`.
    /// A bad or missing endpoint is bad usage (exit 2), as in the other commands.
    pub fn endpoint(&self) -> Result<Endpoint> {
        let bad = |e: anyhow::Error| crate::cli::usage(format!("{e:#}"));
        match (&self.connect, &self.port) {
            (Some(c), _) => c.parse().map_err(bad),
            (None, Some(p)) if p.starts_with("tcp:") || p.starts_with("serial:") => {
                p.parse().map_err(bad)
            }
            (None, Some(p)) if p.is_empty() => Err(crate::cli::usage("--port: empty")),
            (None, Some(p)) => Ok(Endpoint::Serial { path: p.clone(), baud: self.baud }),
            (None, None) => Err(crate::cli::usage(
                "no head given: --connect tcp:HOST:PORT (hvs emulate), --connect serial:PATH[@BAUD] or --port DEVICE (a serial port)",
            )),
        }
    }
}

/// `hvs head`.
pub fn run(args: &Args) -> Result<()> {
    if args.timeout_ms == 0 {
        return Err(crate::cli::usage("--timeout-ms must be at least 1"));
    }
    let timeout = Duration::from_millis(args.timeout_ms);
    let endpoint = args.endpoint()?;
    // Inputs are read before the head is contacted: a bad file is named as such, even when
    // no head answers.
    let points_read = match &args.command {
        HeadCommand::Estimate { points, output } => {
            if let Some(out) = output {
                check_not_input("-o", out, &[("--points", points)])?;
            }
            Some(read_stereo_points(points)?)
        }
        _ => None,
    };
    // A Look from images is located before the head is contacted too.
    let look_point = match &args.command {
        HeadCommand::Look {
            model: Some(m), left: Some(l), right: Some(r), at: Some(at), ..
        } => {
            let p = crate::cli::parse_at(at)?;
            let model = crate::vision::load_stereo_model(m)?;
            crate::cli::check_at(m, &model.blob, l, p)?;
            let located = crate::depth::locate_files_with(m, &model.blob, l, r, &[p])?;
            let f = located.found[0];
            let Some(rp) = f.right else {
                let why = located.warnings.iter().map(|w| format!(" ({w})")).collect::<String>();
                bail!("--at {at}: no trustworthy match in {}: {}{why}", r.display(), f.status);
            };
            eprintln!(
                "located ({}, {}) in {} at ({}, {}) (score {:.3})",
                p[0],
                p[1],
                r.display(),
                rp[0] as f32,
                rp[1] as f32,
                f.score
            );
            Some(StereoPoint {
                u_l: p[0] as f32,
                v_l: p[1] as f32,
                u_r: rp[0] as f32,
                v_r: rp[1] as f32,
            })
        }
        HeadCommand::Look {
            u_l: Some(u_l),
            v_l: Some(v_l),
            u_r: Some(u_r),
            v_r: Some(v_r),
            ..
        } => Some(StereoPoint { u_l: *u_l, v_l: *v_l, u_r: *u_r, v_r: *v_r }),
        HeadCommand::Look { .. } => {
            bail!("look: give U_L V_L U_R V_R, or --model, --left, --right and --at")
        }
        _ => None,
    };
    let mut link = connect(&endpoint, timeout)?;
    // The pixels were found with --model's geometry: the head must run that model.
    if let HeadCommand::Look { model: Some(m), .. } = &args.command {
        let info = expect(link.request(RequestBody::Info)?, "Info", |b| match b {
            ResponseBody::Info(i) => Some(i),
            _ => None,
        })?;
        check_runs(m, &info)?;
    }
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
            let pts = points_read.as_deref().unwrap_or_default();
            let mut csv = String::from(ESTIMATE_HEADER);
            for (line, p) in pts {
                match link.request(RequestBody::Estimate(*p))? {
                    ResponseBody::Estimate(e) => csv.push_str(&estimate_row(p, &e)),
                    // A point without an estimate keeps its row, with empty coordinates.
                    ResponseBody::Error(code) => {
                        eprintln!(
                            "warning: {}:{line}: no estimate: {}",
                            points.display(),
                            error_text(code)
                        );
                        csv.push_str(&no_estimate_row(p));
                    }
                    other => bail!(
                        "{}:{line}: head answered Estimate with an unexpected {other:?}",
                        points.display()
                    ),
                }
            }
            match output {
                Some(path) => write_bytes(path, csv.as_bytes())?,
                None => out.write_all(csv.as_bytes())?,
            }
        }
        HeadCommand::Look { .. } => {
            let p = look_point.ok_or_else(|| anyhow::anyhow!("look: no point"))?;
            let l = expect(link.request(RequestBody::Look(p))?, "Look", |b| match b {
                ResponseBody::Look(l) => Some(l),
                _ => None,
            })?;
            writeln!(
                out,
                "target x={} y={} z={} cm ({:?}, in_range={})",
                l.estimate.x, l.estimate.y, l.estimate.z, l.estimate.source, l.estimate.in_range
            )?;
            writeln!(
                out,
                "joints deg: {}{}",
                joints_text(&l.target),
                if l.limited { " (limited)" } else { "" }
            )?;
        }
        HeadCommand::Home => {
            expect(link.request(RequestBody::Home)?, "Home", |b| {
                matches!(b, ResponseBody::Home).then_some(())
            })?;
            writeln!(out, "homing")?;
        }
        HeadCommand::Posture { joints } => {
            let j = parse_joints(joints)?;
            write_state(&mut out, &client::posture(&mut link, &j)?)?;
        }
        HeadCommand::State => {
            write_state(&mut out, &client::state(&mut link)?)?;
        }
        HeadCommand::Bench { count } => {
            let p = StereoPoint { u_l: 330.0, v_l: 241.0, u_r: 300.0, v_r: 239.0 };
            let b = expect(
                link.request(RequestBody::Bench { point: p, count: *count })?,
                "Bench",
                |b| match b {
                    ResponseBody::Bench(d) => Some(d),
                    _ => None,
                },
            )
            .context(
                "Bench runs on firmware built with `--features bench` (bash firmware/measure.sh builds and runs it in QEMU with -icount shift=0)",
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

/// `A,B,C,D,E`: five joint angles in degrees (`nan` keeps an axis' goal; infinities refused).
fn parse_joints(s: &str) -> Result<Joints> {
    let v: Vec<&str> = s.split(',').map(str::trim).collect();
    if v.len() != 5 {
        return Err(crate::cli::usage(format!(
            "posture: expected five angles NECK_PAN,NECK_TILT,EYE_TILT,LEFT_EYE_PAN,RIGHT_EYE_PAN, got {s:?}"
        )));
    }
    let mut j = [0.0f32; 5];
    for (k, x) in v.iter().enumerate() {
        j[k] = match x.parse::<f32>() {
            Ok(a) if !a.is_infinite() => a,
            _ => {
                return Err(crate::cli::usage(format!(
                    "posture: angle {} ({x:?}) is not a finite number of degrees (or nan)",
                    k + 1
                )))
            }
        };
    }
    Ok(Joints(j))
}

/// `neck_pan=.. neck_tilt=.. ..` (degrees), the joints named as the CSV columns are.
fn joints_text(j: &Joints) -> String {
    crate::data::dataset::JOINT_COLUMNS
        .iter()
        .zip(j.0)
        .map(|(n, a)| format!("{n}={a}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The head's state: its joints and the move's goal in degrees, its clock, whether it moves.
fn write_state(out: &mut impl Write, s: &StateData) -> Result<()> {
    writeln!(out, "joints deg: {}", joints_text(&s.joints))?;
    writeln!(out, "goal deg: {}", joints_text(&s.goal))?;
    writeln!(out, "ticks={} moving={}", s.ticks, s.moving)?;
    Ok(())
}

/// Refuses a `look --model M` when the head runs another model (or the fallback): the
/// model's metadata (shape, seed, training-set hash and size, training error) against the
/// head's `Info`.
fn check_runs(
    model_path: &std::path::Path,
    info: &hvs_shared::runtime::protocol::InfoData,
) -> Result<()> {
    let blob = crate::data::model::load(model_path)?.blob;
    let m = &blob.meta;
    let Some(h) = info.model else {
        bail!(
            "--model {}: the head runs no model (fallback mode): flash it first (hvs flash)",
            model_path.display()
        );
    };
    if !hvs_shared::runtime::protocol::ModelInfo::of(&blob).same_as(&h) {
        bail!(
            "--model {} is not the model the head runs (head: generation {}, seed {}, training set {:016x} of {} points; file: seed {}, training set {:016x} of {} points): give the model the head runs, or flash this one",
            model_path.display(),
            info.generation,
            h.seed,
            h.train_hash,
            h.train_points,
            m.seed,
            m.train_hash,
            m.train_points
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn posture_takes_five_finite_angles_or_nan() {
        let j = super::parse_joints("10, -200,nan,2,-2.5").unwrap();
        assert_eq!((j.0[0], j.0[1], j.0[3], j.0[4]), (10.0, -200.0, 2.0, -2.5));
        assert!(j.0[2].is_nan());
        for bad in ["1,2,3,4", "1,2,3,4,5,6", "1,2,x,4,5", "1,2,inf,4,5", "1,2,3,4,-inf", ""] {
            assert!(super::parse_joints(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn endpoint_from_flags() {
        let a = Args {
            connect: None,
            port: Some("/dev/ttyACM0".into()),
            baud: 9600,
            timeout_ms: 1,
            command: HeadCommand::Ping,
        };
        assert_eq!(
            a.endpoint().unwrap(),
            Endpoint::Serial { path: "/dev/ttyACM0".into(), baud: 9600 }
        );
        // --port takes the endpoints hvs track and hvs view take.
        let with = |p: &str| Args { port: Some(p.into()), ..a.clone() }.endpoint().unwrap();
        assert_eq!(with("tcp:127.0.0.1:4444"), "tcp:127.0.0.1:4444".parse().unwrap());
        assert_eq!(
            with("serial:/dev/ttyUSB1@57600"),
            Endpoint::Serial { path: "/dev/ttyUSB1".into(), baud: 57600 }
        );
    }
}
