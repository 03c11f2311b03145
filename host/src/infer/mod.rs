//! Batch inference of a weights blob over many points, bit-identical to
//! `hvs_shared::runtime::blob::ModelBlob::infer` (the head's computation).
//!
//! Common topologies (4 or 9 inputs, 1-10 hidden units, 1 or 3 outputs, with or without the
//! default family's linear skip term) run through the fixed-size
//! `hvs_shared::runtime::mlp::Mlp<I, H, O>` evaluated `lanes::LANES` points at a time by the
//! auto-vectorised, bit-identical kernel in `lanes` (the scalar sigmoid applied lane by lane),
//! then the family's output map and the output frame (`ModelBlob::finish`, per row); anything
//! else through the runtime-sized `infer_flat`. Both give the same
//! bits (a property test in `hvs-shared`, and the tests here and in `lanes`). Large batches
//! are split into chunks run in parallel with `rayon`; the result does not depend on the
//! thread count.

use crate::data::csv::Table;
use crate::data::model::input_names;
use anyhow::{anyhow, Result};
use hvs_shared::runtime::blob::{ModelBlob, OutputFrame};
use hvs_shared::runtime::mlp::{infer_flat, Mlp, MlpError, OutputMap};
use rayon::prelude::*;

mod lanes;

/// The note `hvs predict`, `hvs depth` and `hvs locate` print when `outside` of the `total`
/// points they answered lie outside the model's input box (its training pixels, or joints):
/// the net's answers there are extrapolations (a net of the thesis' 72 middle points gives
/// depths 10-20 % off near the image's edges). `None` when none do.
pub fn extrapolation_note(outside: usize, total: usize, what: &str) -> Option<String> {
    (outside > 0).then(|| {
        format!(
            "note: {outside} of {total} {what} lie outside the input box the model was trained on; their estimates are extrapolations"
        )
    })
}

/// Points per parallel chunk.
const CHUNK: usize = 16 * 1024;

/// A failed point: its index and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PointError {
    /// Index of the point (row) in the batch.
    pub index: usize,
    /// The reason.
    pub error: MlpError,
}

/// A batch kernel: inputs, outputs -> the first failing row and why.
type BatchFn = dyn Fn(&[f32], &mut [f32]) -> Result<(), (usize, MlpError)> + Send + Sync;

enum Kernel {
    Flat,
    Fixed(Box<BatchFn>),
}

/// A model ready to run on batches of points.
pub struct Predictor<'a> {
    blob: &'a ModelBlob,
    kernel: Kernel,
}

fn fixed<const I: usize, const H: usize, const O: usize>(blob: &ModelBlob) -> Option<Kernel> {
    let flat = blob.flat();
    if flat.in_offset.len() != I || flat.hidden != H || flat.out_offset.len() != O {
        return None;
    }
    let arr = |s: &[f32]| -> Option<[f32; I]> { s.try_into().ok() };
    let arr_o = |s: &[f32]| -> Option<[f32; O]> { s.try_into().ok() };
    let m: Mlp<I, H, O> = Mlp::from_params(
        flat.params,
        flat.output,
        arr(flat.in_offset)?,
        arr(flat.in_scale)?,
        arr_o(flat.out_offset)?,
        arr_o(flat.out_scale)?,
    )
    .ok()?;
    // A family with a skip term: its weights, `s[k][0..I]` per output.
    let skip: Option<lanes::Skip<I, O>> = match flat.skip.len() {
        0 => None,
        n if n == I * O => {
            Some(core::array::from_fn(|k| core::array::from_fn(|i| flat.skip[k * I + i])))
        }
        _ => return None,
    };
    let owned = blob.clone();
    // Point by point (blocks with a non-finite value, the last partial block): the shared
    // inference's net, `infer_flat` (the bits of `Mlp::infer` for a net without skip term).
    let scalar = |b: &ModelBlob, x: &[f32; I]| -> Result<[f32; O], MlpError> {
        let mut y = [0.0f32; O];
        infer_flat(&b.flat(), x, &mut y).map(|()| y)
    };
    if blob.family.output_map == OutputMap::Direct && blob.frame == OutputFrame::Head {
        return Some(Kernel::Fixed(Box::new(move |x: &[f32], out: &mut [f32]| {
            lanes::run_with(&m, skip.as_ref(), x, out, |x| scalar(&owned, x))
        })));
    }
    // The lanes stop at the net's de-normalised outputs; the family's map and the output frame
    // (`ModelBlob::finish`) follow row by row (the rows before a failing one are written, so
    // the first failure is reported either way).
    Some(Kernel::Fixed(Box::new(move |x: &[f32], out: &mut [f32]| {
        let done = lanes::run_with(&m, skip.as_ref(), x, out, |x| scalar(&owned, x));
        let rows = match done {
            Ok(()) => out.len() / O,
            Err((r, _)) => r,
        };
        for (r, (xi, o)) in x.chunks_exact(I).zip(out.chunks_exact_mut(O)).take(rows).enumerate() {
            owned.finish(xi, o).map_err(|e| (r, e))?;
        }
        done
    })))
}

macro_rules! dispatch_h {
    ($blob:expr, $i:expr, $h:expr, $o:expr; $I:literal, $O:literal; $($H:literal)*) => {{
        let mut k = None;
        $( if $i == $I && $h == $H && $o == $O { k = fixed::<$I, $H, $O>($blob); } )*
        k
    }};
}

/// The fixed-size kernel for `I-H-O` nets with `I` in {4, 9}, `H` in 1..=10, `O` in {1, 3}.
fn fixed_kernel(blob: &ModelBlob) -> Option<Kernel> {
    let (i, h, o) = (blob.n_inputs(), blob.topology.hidden as usize, blob.n_outputs());
    match (i, o) {
        (4, 3) => dispatch_h!(blob, i, h, o; 4, 3; 1 2 3 4 5 6 7 8 9 10),
        (4, 1) => dispatch_h!(blob, i, h, o; 4, 1; 1 2 3 4 5 6 7 8 9 10),
        (9, 3) => dispatch_h!(blob, i, h, o; 9, 3; 1 2 3 4 5 6 7 8 9 10),
        (9, 1) => dispatch_h!(blob, i, h, o; 9, 1; 1 2 3 4 5 6 7 8 9 10),
        _ => None,
    }
}

impl<'a> Predictor<'a> {
    /// Prepares `blob` (already validated by `decode`).
    pub fn new(blob: &'a ModelBlob) -> Self {
        let kernel = fixed_kernel(blob).unwrap_or(Kernel::Flat);
        Predictor { blob, kernel }
    }

    /// Whether the fixed-size fast path is used.
    pub fn is_fixed(&self) -> bool {
        matches!(self.kernel, Kernel::Fixed(_))
    }

    /// Inputs per point.
    pub fn n_inputs(&self) -> usize {
        self.blob.n_inputs()
    }

    /// Outputs per point.
    pub fn n_outputs(&self) -> usize {
        self.blob.n_outputs()
    }

    /// Inputs and outputs per point, after checking that `inputs` holds whole points and
    /// `out` room for exactly their outputs ([`MlpError::Shape`] at point 0 if not).
    fn check_shape(&self, inputs: &[f32], out: &[f32]) -> Result<(usize, usize), PointError> {
        let (ni, no) = (self.n_inputs(), self.n_outputs());
        if inputs.len() % ni != 0 || out.len() != inputs.len() / ni * no {
            return Err(PointError { index: 0, error: MlpError::Shape });
        }
        Ok((ni, no))
    }

    /// Runs `inputs` (row-major, `n_inputs` per point) into `out` (`n_outputs` per point) on
    /// the current thread. Stops at the first failing point.
    pub fn run_serial(&self, inputs: &[f32], out: &mut [f32]) -> Result<(), PointError> {
        let (ni, no) = self.check_shape(inputs, out)?;
        match &self.kernel {
            Kernel::Fixed(f) => {
                f(inputs, out).map_err(|(index, error)| PointError { index, error })
            }
            Kernel::Flat => {
                for (r, (xi, oi)) in
                    inputs.chunks_exact(ni).zip(out.chunks_exact_mut(no)).enumerate()
                {
                    self.blob.infer(xi, oi).map_err(|error| PointError { index: r, error })?;
                }
                Ok(())
            }
        }
    }

    /// As [`Predictor::run_serial`], in parallel chunks; the error reported is the one of the
    /// first failing point.
    pub fn run(&self, inputs: &[f32], out: &mut [f32]) -> Result<(), PointError> {
        let (ni, no) = self.check_shape(inputs, out)?;
        let errors: Vec<PointError> = inputs
            .par_chunks(CHUNK * ni)
            .zip(out.par_chunks_mut(CHUNK * no))
            .enumerate()
            .filter_map(|(c, (x, o))| {
                self.run_serial(x, o)
                    .err()
                    .map(|e| PointError { index: c * CHUNK + e.index, error: e.error })
            })
            .collect();
        match errors.into_iter().min_by_key(|e| e.index) {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// As [`Predictor::run`], going on past failing points: each gets `+inf` for all its
    /// outputs, the others their estimates (the same bits); returns how many failed.
    pub fn run_each(&self, inputs: &[f32], out: &mut [f32]) -> Result<usize, PointError> {
        let (ni, no) = self.check_shape(inputs, out)?;
        let failed = inputs
            .par_chunks(CHUNK * ni)
            .zip(out.par_chunks_mut(CHUNK * no))
            .map(|(x, o)| {
                let (mut r, mut failed) = (0, 0);
                while r * ni < x.len() {
                    match self.run_serial(&x[r * ni..], &mut o[r * no..]) {
                        Ok(()) => break,
                        Err(e) => {
                            let bad = r + e.index;
                            o[bad * no..(bad + 1) * no].fill(f32::INFINITY);
                            failed += 1;
                            r = bad + 1;
                        }
                    }
                }
                failed
            })
            .sum();
        Ok(failed)
    }

    /// Allocating form of [`Predictor::run`].
    pub fn predict(&self, inputs: &[f32]) -> Result<Vec<f32>, PointError> {
        let mut out = vec![0.0f32; inputs.len() / self.n_inputs().max(1) * self.n_outputs()];
        self.run(inputs, &mut out)?;
        Ok(out)
    }
}

/// The inputs of a data set as the f32 the model sees; `Err((row, column))` names the first
/// value outside the f32 range.
pub fn to_f32(inputs: &[f64], n_inputs: usize) -> Result<Vec<f32>, (usize, usize)> {
    let out: Vec<f32> = inputs.iter().map(|v| *v as f32).collect();
    let n = n_inputs.max(1);
    match out.iter().position(|v| !v.is_finite()) {
        Some(k) => Err((k / n, k % n)),
        None => Ok(out),
    }
}

/// Runs the model on every row of `table`: the f32 inputs and the outputs, row-major.
/// Errors name the file, line and (for range errors) the column.
pub fn infer_table(blob: &ModelBlob, table: &Table) -> Result<(Vec<f32>, Vec<f32>)> {
    let ni = blob.n_inputs();
    let names = input_names(blob.topology.inputs);
    let x = to_f32(&table.data.inputs, ni).map_err(|(r, c)| {
        anyhow!(
            "{}: column \"{}\": {} does not fit the f32 the model computes in",
            table.at(r),
            names.get(c).copied().unwrap_or("?"),
            table.data.inputs[r * ni + c]
        )
    })?;
    let p = Predictor::new(blob);
    let y = p.predict(&x).map_err(|PointError { index, error }| {
        anyhow!("{}: the model cannot estimate this point: {error}", table.at(index))
    })?;
    Ok((x, y))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use hvs_shared::runtime::blob::{
        Algorithm, Family, InputKind, OutputKind, Topology, TrainingMeta,
    };
    use hvs_shared::runtime::mlp::{param_count, Activation};

    /// A deterministic hand-made blob of any 4-input topology.
    pub(crate) fn blob(hidden: u8, outputs: OutputKind, inputs: InputKind) -> ModelBlob {
        fn v<const N: usize>(s: &[f32]) -> heapless::Vec<f32, N> {
            heapless::Vec::from_slice(s).unwrap()
        }
        let (ni, no) = (inputs.len(), outputs.len());
        let n = param_count(ni, hidden as usize, no);
        let params = (0..n)
            .map(|k| ((k as u32).wrapping_mul(2_654_435_761) % 2000) as f32 / 1000.0 - 1.0)
            .collect::<Vec<_>>();
        let inputs_off: Vec<f32> = (0..ni).map(|k| if k < 4 { 300.0 } else { 0.0 }).collect();
        let inputs_scale: Vec<f32> = (0..ni).map(|k| if k < 4 { 0.02 } else { 0.1 }).collect();
        ModelBlob {
            generation: 1,
            topology: Topology { inputs, hidden, outputs, output_activation: Activation::Linear },
            in_offset: v(&inputs_off),
            in_scale: v(&inputs_scale),
            out_offset: v(&[0.0, 0.0, 115.0][3 - no..]),
            out_scale: v(&[3.0, 2.0, 50.0][3 - no..]),
            params: v(&params),
            in_min: v(&vec![0.0; ni]),
            in_max: v(&vec![640.0; ni]),
            meta: TrainingMeta {
                seed: 0,
                train_hash: 0,
                train_points: 72,
                train_error_pct: 1.0,
                algorithm: Algorithm::Other,
                restarts: 1,
            },
            fallback: None,
            family: hvs_shared::runtime::blob::Family::THESIS,
            matcher: None,
            frame: hvs_shared::runtime::blob::OutputFrame::Head,
            image_size: None,
            parent: None,
        }
    }

    #[test]
    fn every_path_gives_the_bits_of_the_shared_inference() {
        let cases = [
            (5, OutputKind::Xyz, InputKind::Stereo, true),
            (5, OutputKind::Z, InputKind::Stereo, true),
            (7, OutputKind::Xyz, InputKind::StereoJoints, true),
            (17, OutputKind::Xyz, InputKind::Stereo, false),
        ];
        for (h, o, i, fixed) in cases {
            let b = blob(h, o, i);
            let p = Predictor::new(&b);
            assert_eq!(p.is_fixed(), fixed);
            let ni = i.len();
            let n = 40_000; // more than two chunks
            let x: Vec<f32> =
                (0..n * ni).map(|k| 200.0 + ((k * 7919) % 24_000) as f32 / 100.0).collect();
            let y = p.predict(&x).unwrap();
            let mut serial = vec![0.0; y.len()];
            p.run_serial(&x, &mut serial).unwrap();
            for r in 0..n {
                let mut want = [0.0f32; 3];
                b.infer(&x[r * ni..(r + 1) * ni], &mut want[..o.len()]).unwrap();
                for k in 0..o.len() {
                    assert_eq!(y[r * o.len() + k].to_bits(), want[k].to_bits());
                    assert_eq!(serial[r * o.len() + k].to_bits(), want[k].to_bits());
                }
            }
        }
    }

    #[test]
    fn inverse_depth_family_gives_the_bits_of_the_shared_inference() {
        for (h, o, i, fixed) in [
            (5, OutputKind::Xyz, InputKind::Stereo, true),
            (5, OutputKind::Z, InputKind::Stereo, true),
            (7, OutputKind::Xyz, InputKind::StereoJoints, true),
            (17, OutputKind::Xyz, InputKind::Stereo, false),
        ] {
            let mut b = blob(h, o, i);
            let no = o.len();
            let ni = i.len();
            let n = 3000;
            let x: Vec<f32> = (0..(n * ni) as u64)
                .map(|k| {
                    let h = (k + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
                    if (k as usize) % ni < 4 {
                        200.0 + (h % 24_000) as f32 / 100.0
                    } else {
                        (h % 4_000) as f32 / 100.0 - 20.0
                    }
                })
                .collect();
            // Offset the last output by minus row 150's value: its 1/Z (and that of any row
            // with the same value) is exactly 0, an infinite depth; the rows below it are
            // negative depths, still estimates.
            b.out_offset[no - 1] = 0.0;
            let last: Vec<f32> = (0..n)
                .map(|r| {
                    let mut y = [0.0f32; 3];
                    b.infer(&x[r * ni..(r + 1) * ni], &mut y[..no]).unwrap();
                    y[no - 1]
                })
                .collect();
            b.out_offset[no - 1] = -last[150];
            b.family = hvs_shared::runtime::blob::Family::INVERSE_DEPTH;
            let p = Predictor::new(&b);
            assert_eq!(p.is_fixed(), fixed);
            let mut first_bad = None;
            let mut want = vec![0.0f32; n * no];
            for r in 0..n {
                match b.infer(&x[r * ni..(r + 1) * ni], &mut want[r * no..(r + 1) * no]) {
                    Ok(()) => {}
                    Err(e) => {
                        first_bad.get_or_insert((r, e));
                    }
                }
            }
            let (bad, err) = first_bad.expect("row 150 has an infinite depth");
            assert!((100..=150).contains(&bad), "{bad}");
            assert_eq!(err, MlpError::NonFiniteOutput);
            // Up to the first bad row the bits agree; the error names that row.
            let got = p.predict(&x[..bad * ni]).unwrap();
            assert_eq!(
                got.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                want[..bad * no].iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            );
            assert_eq!(p.predict(&x).unwrap_err(), PointError { index: bad, error: err });
        }
    }

    #[test]
    fn first_failing_point_is_reported() {
        let b = blob(5, OutputKind::Xyz, InputKind::Stereo);
        let p = Predictor::new(&b);
        let mut x = vec![320.0f32; 4 * 50_000];
        x[4 * 45_000 + 2] = f32::NAN;
        x[4 * 20_000 + 1] = f32::INFINITY;
        let e = p.predict(&x).unwrap_err();
        assert_eq!(e.index, 20_000);
        assert_eq!(e.error, MlpError::NonFiniteInput);
        assert_eq!(to_f32(&[1.0, 2.0, 4.0, 1e300], 2), Err((1, 1)));
    }

    /// `run_each` goes past failing points (two in one chunk, one in another, the last
    /// point): they get +inf, every other point the bits of `ModelBlob::infer`.
    #[test]
    fn run_each_marks_the_failing_points_and_keeps_the_others() {
        for family in [Family::THESIS, Family::INVERSE_DEPTH_SKIP] {
            let mut b = blob(5, OutputKind::Xyz, InputKind::Stereo);
            if family.skip != Family::THESIS.skip {
                b.params.extend_from_slice(&[0.01; 12]).unwrap();
            }
            b.family = family;
            let n = 40_000;
            let mut x: Vec<f32> =
                (0..n * 4).map(|k| 200.0 + ((k * 7919) % 24_000) as f32 / 100.0).collect();
            let bad = [17usize, 18, 1000, 20_000, n - 1];
            for (i, &r) in bad.iter().enumerate() {
                x[r * 4 + i % 4] = if i % 2 == 0 { f32::NAN } else { f32::NEG_INFINITY };
            }
            let mut out = vec![0.0f32; n * 3];
            assert_eq!(Predictor::new(&b).run_each(&x, &mut out), Ok(bad.len()));
            for r in 0..n {
                let mut want = [0.0f32; 3];
                let got: [f32; 3] = out[r * 3..r * 3 + 3].try_into().unwrap();
                match b.infer(&x[r * 4..r * 4 + 4], &mut want) {
                    Ok(()) => assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "row {r}"),
                    Err(_) => {
                        assert!(bad.contains(&r), "row {r}");
                        assert_eq!(got, [f32::INFINITY; 3]);
                    }
                }
            }
        }
    }
}
