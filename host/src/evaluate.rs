//! Depth error of one or more estimators on a set with ground truth: e_ma (eq. 4.1-5, cm)
//! and its percentage form, per ground-truth depth, with the mean over all points and the
//! worst depth, as the thesis reports them (Figs. 4.8-4.12, 4.16-4.19).
//!
//! Grouping: by exact ground-truth depth when the set has at most [`MAX_EXACT_DEPTHS`]
//! distinct depths (board sets); otherwise (random volume points) into [`BINS`] equal-width
//! depth bins. "mean" is e_ma over all points, "worst" the largest per-depth e_ma, "best" the
//! smallest. A missing estimate (NaN or infinite, e.g. zero disparity) counts as an infinite
//! error, so a method that fails can never look good.
//!
//! The estimators themselves come from `hvs-shared` (see [`model_depths`],
//! [`traditional_depths`], [`optimal_depths`]).

use crate::data::dataset::Dataset;
use crate::infer::{PointError, Predictor};
use hvs_shared::runtime::blob::ModelBlob;
use hvs_shared::runtime::gaze::Joints;
use hvs_shared::runtime::traditional::{traditional_depth_signed, Calibration};
use hvs_shared::sim::camera::{Distortion, Rig};
use hvs_shared::sim::metrics::EmaAcc;
use hvs_shared::sim::posture::HeadRig;
use hvs_shared::sim::triangulate::optimal_rig as optimal;
use serde::Serialize;

/// Most distinct depths reported one by one.
pub const MAX_EXACT_DEPTHS: usize = 50;
/// Depth bins used beyond that.
pub const BINS: usize = 10;

/// e_ma of one estimator over a group of points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Ema {
    /// e_ma (cm).
    pub e_ma_cm: f64,
    /// e_ma in percent of the true depth.
    pub e_ma_pct: f64,
    /// Largest single-point percentage error.
    pub max_pct: f64,
}

impl From<&EmaAcc> for Ema {
    fn from(a: &EmaAcc) -> Self {
        Ema { e_ma_cm: a.e_ma(), e_ma_pct: a.e_ma_pct(), max_pct: a.max_pct() }
    }
}

/// One depth (or depth bin) of the table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DepthRow {
    /// Smallest true depth in the group (cm).
    pub z_min: f64,
    /// Largest true depth in the group (cm); equal to `z_min` for exact depths.
    pub z_max: f64,
    /// Points in the group.
    pub points: usize,
    /// e_ma of each method, in the order of [`Evaluation::methods`].
    pub methods: Vec<Ema>,
}

/// Summary of one method.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodSummary {
    /// Name.
    pub name: String,
    /// e_ma over all points.
    pub mean: Ema,
    /// Largest per-depth e_ma (percent).
    pub worst_depth_pct: f64,
    /// Smallest per-depth e_ma (percent).
    pub best_depth_pct: f64,
    /// Points without an estimate.
    pub missing: usize,
}

/// The whole comparison.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Evaluation {
    /// Points evaluated.
    pub points: usize,
    /// Whether rows are exact depths (`true`) or depth bins.
    pub exact_depths: bool,
    /// Per-method summaries.
    pub methods: Vec<MethodSummary>,
    /// Per-depth rows, nearest first.
    pub depths: Vec<DepthRow>,
}

/// Estimated depths of a named method, one per row (NaN where it has no answer).
#[derive(Debug, Clone, PartialEq)]
pub struct Method {
    /// Name shown in tables.
    pub name: String,
    /// Estimated Z per row (cm).
    pub z: Vec<f64>,
}

/// Compares `methods` against the true depths of `truth` (which has ground truth).
pub fn evaluate(truth: &Dataset, methods: &[Method]) -> Evaluation {
    let z: Vec<f64> = truth.targets.iter().map(|t| t[2]).collect();
    let mut distinct: Vec<f64> = z.clone();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    let exact = distinct.len() <= MAX_EXACT_DEPTHS;
    let (lo, hi) =
        (distinct.first().copied().unwrap_or(0.0), distinct.last().copied().unwrap_or(0.0));
    let n_groups = if exact { distinct.len() } else { BINS };
    let group_of = |zt: f64| -> usize {
        if exact {
            distinct.partition_point(|d| *d < zt)
        } else {
            let f = (zt - lo) / (hi - lo) * BINS as f64;
            (f as usize).min(BINS - 1)
        }
    };
    let mut acc = vec![vec![EmaAcc::default(); methods.len()]; n_groups];
    let mut all = vec![EmaAcc::default(); methods.len()];
    let mut zr = vec![(f64::INFINITY, f64::NEG_INFINITY); n_groups];
    let mut missing = vec![0usize; methods.len()];
    for (i, &zt) in z.iter().enumerate() {
        let g = group_of(zt);
        zr[g] = (zr[g].0.min(zt), zr[g].1.max(zt));
        for (m, method) in methods.iter().enumerate() {
            let zh = method.z.get(i).copied().unwrap_or(f64::NAN);
            if !zh.is_finite() {
                missing[m] += 1;
            }
            acc[g][m].add(zt, zh);
            all[m].add(zt, zh);
        }
    }
    let depths: Vec<DepthRow> = acc
        .iter()
        .zip(&zr)
        .filter(|(a, _)| a.first().is_some_and(|x| x.count() > 0))
        .map(|(a, r)| DepthRow {
            z_min: r.0,
            z_max: r.1,
            points: a[0].count() as usize,
            methods: a.iter().map(Ema::from).collect(),
        })
        .collect();
    let summaries = methods
        .iter()
        .enumerate()
        .map(|(m, method)| {
            let per: Vec<f64> = depths.iter().map(|d| d.methods[m].e_ma_pct).collect();
            MethodSummary {
                name: method.name.clone(),
                mean: Ema::from(&all[m]),
                worst_depth_pct: per.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                best_depth_pct: per.iter().copied().fold(f64::INFINITY, f64::min),
                missing: missing[m],
            }
        })
        .collect();
    Evaluation { points: z.len(), exact_depths: exact, methods: summaries, depths }
}

/// The model's depth for every row (f32 inference of `hvs-shared`, widened to f64).
pub fn model_depths(blob: &ModelBlob, data: &Dataset) -> Result<Vec<f64>, ModelDepthError> {
    if data.n_inputs != blob.n_inputs() {
        return Err(ModelDepthError::Inputs { model: blob.n_inputs(), data: data.n_inputs });
    }
    let x = crate::infer::to_f32(&data.inputs, data.n_inputs).map_err(ModelDepthError::Range)?;
    let p = Predictor::new(blob);
    let y = p.predict(&x).map_err(ModelDepthError::Point)?;
    Ok(depth_column(&y, blob.n_outputs()))
}

/// The depths in a model's outputs `y` (`n_outputs` a row, row-major): `Z` is a model's last
/// output (of `X, Y, Z`, or the only one), widened to f64.
pub fn depth_column(y: &[f32], n_outputs: usize) -> Vec<f64> {
    y.chunks_exact(n_outputs).map(|o| f64::from(o[n_outputs - 1])).collect()
}

/// Why the model could not be run on a set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ModelDepthError {
    /// The set's number of inputs differs from the model's.
    Inputs {
        /// Inputs of the model.
        model: usize,
        /// Inputs of the set.
        data: usize,
    },
    /// Row and column of an input outside the f32 range.
    Range((usize, usize)),
    /// A point failed.
    Point(PointError),
}

/// The traditional method's depth (eq. 3.1-17, evaluated as printed, negative disparities
/// included, as in the thesis' figures) with calibration `cal`; NaN at zero disparity.
pub fn traditional_depths(cal: &Calibration, data: &Dataset) -> Vec<f64> {
    (0..data.len())
        .map(|i| {
            let r = data.row(i);
            traditional_depth_signed(cal.phi as f64, cal.half_baseline as f64, r[0], r[2])
                .unwrap_or(f64::NAN)
        })
        .collect()
}

/// Optimal triangulation with the true rig (least reprojection error): the accuracy floor on
/// rounded pixels. NaN where it fails.
///
/// On a posture-aware set (nine inputs: the pixels, then the joint angles of
/// [`crate::data::dataset::JOINT_COLUMNS`] in degrees) each row is triangulated with the rig's
/// cameras at that row's posture (`hvs_shared::sim::posture::HeadRig::new(rig)`: the simulator's
/// head, neck axes through the baseline centre, no lens distortion), so the depth is in the
/// head frame like the set's ground truth. A set's lens distortion is not in the file: give
/// it to [`optimal_depths_lens`].
pub fn optimal_depths(rig: &Rig, data: &Dataset) -> Vec<f64> {
    optimal_depths_lens(rig, Distortion::NONE, data)
}

/// [`optimal_depths`] through lenses with radial distortion `lens` (both cameras, as
/// `hvs simulate --distortion`): the rays of the undistorted pixels
/// (`HeadRig::with_distortion`), at the home posture or at each row's posture. Without
/// distortion this is exactly [`optimal_depths`].
pub fn optimal_depths_lens(rig: &Rig, lens: Distortion, data: &Dataset) -> Vec<f64> {
    let head = HeadRig::new(*rig).with_distortion(lens);
    (0..data.len())
        .map(|i| {
            let r = data.row(i);
            let px = [r[0], r[1], r[2], r[3]];
            let p = if let Some(joints) = data.joints(i) {
                head.optimal(&joints, &px)
            } else if lens.is_none() {
                optimal(rig, &px)
            } else {
                head.optimal(&Joints::HOME, &px)
            };
            p.map_or(f64::NAN, |p| p[2])
        })
        .collect()
}

use crate::fmt::pct;

/// Plain-text table of an evaluation: one row per depth, e_ma in cm and % for each method.
pub fn text_table(ev: &Evaluation) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let w = 22;
    let _ = write!(s, "{:>17} {:>6}", "depth (cm)", "points");
    for m in &ev.methods {
        let _ = write!(s, "  {:>w$}", format!("{} e_ma", m.name));
    }
    s.push('\n');
    let cell = |e: &Ema| {
        if e.e_ma_cm.is_finite() {
            format!("{:.3} cm {:>9}", e.e_ma_cm, pct(e.e_ma_pct))
        } else {
            "no estimate".to_string()
        }
    };
    for d in &ev.depths {
        let depth = if d.z_min == d.z_max {
            format!("{}", d.z_min)
        } else {
            format!("{:.1}-{:.1}", d.z_min, d.z_max)
        };
        let _ = write!(s, "{depth:>17} {:>6}", d.points);
        for e in &d.methods {
            let _ = write!(s, "  {:>w$}", cell(e));
        }
        s.push('\n');
    }
    let _ = write!(s, "{:>17} {:>6}", "mean", ev.points);
    for m in &ev.methods {
        let _ = write!(s, "  {:>w$}", cell(&m.mean));
    }
    s.push('\n');
    let _ = write!(s, "{:>17} {:>6}", "worst depth", "");
    for m in &ev.methods {
        let _ = write!(s, "  {:>w$}", pct(m.worst_depth_pct));
    }
    s.push('\n');
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use hvs_shared::runtime::blob::InputKind;

    fn set(points: &[(f64, f64)]) -> Dataset {
        // (u_l - u_r, z): pixels chosen so that Phi 2d / u_sd is easy.
        let mut d = Dataset::new(InputKind::Stereo);
        for &(usd, z) in points {
            d.push(&[320.0 + usd, 240.0, 320.0, 240.0], Some([0.0, 0.0, z]));
        }
        d
    }

    #[test]
    fn per_depth_mean_and_worst_by_hand() {
        let d = set(&[(1.0, 100.0), (1.0, 100.0), (1.0, 50.0)]);
        let m = Method { name: "m".into(), z: vec![98.0, 104.0, 51.0] };
        let ev = evaluate(&d, &[m]);
        assert!(ev.exact_depths);
        assert_eq!(ev.depths.len(), 2);
        assert_eq!((ev.depths[0].z_min, ev.depths[0].points), (50.0, 1));
        assert!((ev.depths[0].methods[0].e_ma_pct - 2.0).abs() < 1e-12);
        assert!((ev.depths[1].methods[0].e_ma_cm - 3.0).abs() < 1e-12);
        assert!((ev.depths[1].methods[0].e_ma_pct - 3.0).abs() < 1e-12);
        let s = &ev.methods[0];
        assert!((s.mean.e_ma_cm - 7.0 / 3.0).abs() < 1e-12);
        assert!((s.mean.e_ma_pct - 8.0 / 3.0).abs() < 1e-12);
        assert!((s.worst_depth_pct - 3.0).abs() < 1e-12);
        assert!((s.best_depth_pct - 2.0).abs() < 1e-12);
        assert_eq!(s.missing, 0);
        assert!(text_table(&ev).contains("worst depth"));
    }

    #[test]
    fn failures_count_as_infinite_and_volume_sets_are_binned() {
        let d = set(&[(1.0, 100.0), (0.0, 60.0)]);
        let cal = Calibration { phi: 100.0, half_baseline: 0.5, u0: 320.0, v0: 240.0 };
        let z = traditional_depths(&cal, &d);
        assert_eq!(z[0], 100.0);
        assert!(z[1].is_nan());
        let ev = evaluate(&d, &[Method { name: "t".into(), z }]);
        assert_eq!(ev.methods[0].missing, 1);
        assert_eq!(ev.methods[0].worst_depth_pct, f64::INFINITY);
        let many: Vec<(f64, f64)> = (0..200).map(|k| (1.0, 65.0 + k as f64 * 0.5)).collect();
        let d = set(&many);
        let ev = evaluate(
            &d,
            &[Method { name: "x".into(), z: d.targets.iter().map(|t| t[2]).collect() }],
        );
        assert!(!ev.exact_depths);
        assert_eq!(ev.depths.len(), BINS);
        assert_eq!(ev.depths.iter().map(|r| r.points).sum::<usize>(), 200);
        assert_eq!(ev.depths[0].z_min, 65.0);
        assert_eq!(ev.depths[BINS - 1].z_max, 164.5);
        assert_eq!(ev.methods[0].worst_depth_pct, 0.0);
    }

    #[test]
    fn the_floor_of_a_posture_set_uses_the_cameras_at_each_rows_posture() {
        use crate::sim::posture::{dataset, simulate};
        use crate::sim::sets::{SetKind, SimOptions};
        use hvs_shared::sim::posture::joints_from_gaze;
        let rig = hvs_shared::sim::presets::CASE_3;
        let head = HeadRig::new(rig);
        // Home, verged 10 degrees, and a turned, tilted, verged posture.
        let postures = [
            Joints::HOME,
            joints_from_gaze(0.0, 0.0, 0.0, 0.0, 10.0),
            joints_from_gaze(25.0, -15.0, 10.0, -12.0, 6.0),
        ];
        let samples = simulate(&head, SetKind::Test, &postures, &SimOptions::default()).unwrap();
        let data = dataset(&samples);
        assert_eq!(data.input_kind(), Some(InputKind::StereoJoints));
        let z = optimal_depths(&rig, &data);
        assert_eq!(z.len(), 3 * 22);
        for (s, zh) in samples.iter().zip(&z) {
            let want = head.optimal(&s.joints, &s.px).unwrap()[2];
            assert_eq!(*zh, want, "{:?}", s.joints);
            // The floor: rounding only, a few percent at most.
            assert!((zh - s.xyz[2]).abs() / s.xyz[2] < 0.05, "{zh} vs {:?}", s.xyz);
        }
        let ev = evaluate(&data, &[Method { name: "optimal".into(), z }]);
        assert_eq!(ev.methods[0].missing, 0);
        assert!(ev.methods[0].mean.e_ma_pct < 2.0, "{:?}", ev.methods[0]);
        // The pixels alone, triangulated with the home rig, are far off at the other postures:
        // what the floor used to be.
        let mut home_only = Dataset::new(InputKind::Stereo);
        for s in &samples {
            home_only.push(&s.px, Some(s.xyz));
        }
        let zh = optimal_depths(&rig, &home_only);
        // At home both are the same least-squares point (two solvers, rounding apart).
        for (a, b) in zh[..22].iter().zip(&optimal_depths(&rig, &data)[..22]) {
            assert!((a - b).abs() < 1e-6 * a, "{a} {b}");
        }
        let off = samples[22..]
            .iter()
            .zip(&zh[22..])
            .filter(|(s, z)| ((**z - s.xyz[2]) / s.xyz[2]).abs() >= 0.2 || z.is_nan())
            .count();
        assert!(off > 30, "{off} of 44");
    }
}
