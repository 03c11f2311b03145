//! The client of a head controller (real, over a serial port, or QEMU's over TCP): one
//! function per request, each turning the head's answer or error code into a value or a
//! message, and the text forms `hvs head` prints (estimate rows in shortest round-trip form, so
//! the bits can be compared with host inference; the `Info` report).

use crate::device::link::{Endpoint, Link};
use anyhow::{bail, Result};
use hvs_shared::runtime::protocol::{
    ErrorCode, EstimateData, InfoData, Joints, Mode, RequestBody, ResponseBody, SlotStatus, Source,
    StateData, StereoPoint,
};
use std::io::Write;
use std::time::Duration;

/// Opens a link and waits until the head answers.
pub fn connect(endpoint: &Endpoint, timeout: Duration) -> Result<Link> {
    let mut link = Link::open(endpoint, timeout)?;
    link.timeout = timeout;
    link.wait_ready(timeout)?;
    Ok(link)
}

/// One estimate through the link; head errors become messages.
pub fn estimate(link: &mut Link, p: &StereoPoint) -> Result<EstimateData> {
    expect(link.request(RequestBody::Estimate(*p))?, "Estimate", |b| match b {
        ResponseBody::Estimate(e) => Some(e),
        _ => None,
    })
}

/// The head's state (`State`, protocol 3): its joints, the move's goal, its clock.
pub fn state(link: &mut Link) -> Result<StateData> {
    expect(link.request(RequestBody::State)?, "State", |b| match b {
        ResponseBody::State(s) => Some(s),
        _ => None,
    })
}

/// A posture command (`Posture`, protocol 3; the head clamps each joint to its limits) and
/// the state the head answers with.
pub fn posture(link: &mut Link, goal: &Joints) -> Result<StateData> {
    expect(link.request(RequestBody::Posture(*goal))?, "Posture", |b| match b {
        ResponseBody::State(s) => Some(s),
        _ => None,
    })
}

pub fn expect<T>(
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

/// The header of `hvs head estimate`'s CSV ([`estimate_row`], [`no_estimate_row`]).
pub const ESTIMATE_HEADER: &str = "u_l,v_l,u_r,v_r,x,y,z,source,in_range\n";

/// The CSV row of a point the head gave no estimate for: its pixels, empty coordinates,
/// `none,false`.
pub fn no_estimate_row(p: &StereoPoint) -> String {
    format!("{},{},{},{},,,,none,false\n", p.u_l, p.v_l, p.u_r, p.v_r)
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

pub fn write_info(out: &mut impl Write, i: &InfoData) -> Result<()> {
    let f = i.firmware;
    writeln!(out, "firmware: {}.{}.{} (protocol {})", f.major, f.minor, f.patch, i.protocol)?;
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
            SlotStatus::UnsupportedTopology { inputs, hidden, outputs } => format!(
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
        "fallback calibration: phi {} px, d {} cm, principal point ({}, {}){}",
        i.fallback.phi,
        i.fallback.half_baseline,
        i.fallback.u0,
        i.fallback.v0,
        if i.fallback == hvs_shared::runtime::traditional::Calibration::BUILT_IN {
            " (the firmware's built-in one)"
        } else {
            ""
        }
    )?;
    if let Some(peak) = i.stack_peak {
        writeln!(out, "stack peak: {peak} B")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn estimate_rows_round_trip_floats_exactly() {
        let p = StereoPoint { u_l: 335.0, v_l: 240.0, u_r: 289.0, v_r: 240.0 };
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
}
