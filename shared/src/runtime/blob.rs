//! The weights blob: the one model format, on flash and on disk.
//!
//! Layout (little endian):
//!
//! | bytes | field |
//! |---|---|
//! | 0..4 | [`MAGIC`] `b"HVSW"` |
//! | 4..6 | format version (u16): [`VERSION`] 4, or 3, 2 or 1 (read, never written) |
//! | 6..10 | payload length `n` (u32), at most [`MAX_PAYLOAD_LEN`] |
//! | 10..10+n | payload: [`ModelBlob`] in `postcard` |
//! | 10+n..14+n | CRC-32 (ISO-HDLC, as zlib) of bytes `0..10+n` |
//!
//! The payload is the fields of [`ModelBlob`] in declaration order. Version 2 added
//! [`ModelBlob::family`] (how the outputs become cm, which exp the sigmoid uses) and
//! [`ModelBlob::matcher`] (optional stereo-matcher geometry); version 3 added
//! [`ModelBlob::frame`] (the frame the net gives its points in); version 4 added the last two,
//! [`ModelBlob::image_size`] (the training images' size) and [`ModelBlob::parent`] (the model
//! this one was updated from). An older payload is the same bytes without the fields its
//! version lacks and decodes with their defaults: the thesis family ([`Family::THESIS`]), no
//! matcher geometry, the head frame ([`OutputFrame::Head`]), no image size, no parent. The
//! fields up to the frame go through serde: for versions 1 and 2 the decoder appends their
//! defaults' encoding (zeros: 5 bytes for version 1, 1 for version 2) to a stack copy of the
//! payload, so one deserializer reads every version. The two version-4 fields are postcard
//! bytes too (`Option`s of varint structs) but are written and read by hand
//! ([`ModelBlob::encode`], [`decode_into`]): serde's code for them cost the head's flash
//! more than it had to spare.
//!
//! Bytes after the CRC are ignored (a flash slot is larger than any blob). Decoding works
//! from a `&[u8]` with no allocation, checks everything before trusting anything, and returns
//! a distinct [`BlobError`] for each way a blob can be wrong. A blob whose bytes decode has a
//! consistent topology, finite parameters and non-zero scales.

use crate::runtime::gaze;
use crate::runtime::mlp::{self, Activation, FlatMlp, Mlp, MlpError, OutputMap};
use crate::runtime::traditional::Calibration;
use heapless::Vec;
use serde::{Deserialize, Serialize};

/// First four bytes of every blob.
pub const MAGIC: [u8; 4] = *b"HVSW";
/// The format version this crate writes (it also reads [`VERSION_3`], [`VERSION_2`] and
/// [`VERSION_1`]).
pub const VERSION: u16 = 4;
/// The third format version: no [`ModelBlob::image_size`] and [`ModelBlob::parent`] fields.
pub const VERSION_3: u16 = 3;
/// The second format version: no [`ModelBlob::frame`] field either.
pub const VERSION_2: u16 = 2;
/// The first format version: no [`ModelBlob::family`] and [`ModelBlob::matcher`] fields
/// either.
pub const VERSION_1: u16 = 1;
/// Postcard bytes of `(Family::THESIS, None::<MatcherGeometry>, OutputFrame::Head)`: the
/// defaults of the serde fields added after version 1, all zeros. A payload of format `v`
/// lacks the last [`tail_len`]`(v)` of them.
const TAIL: [u8; 5] = [0; 5];

/// Bytes of [`TAIL`] a payload of format `version` lacks (0 from version 3 on, whose serde
/// fields are the current ones).
const fn tail_len(version: u16) -> usize {
    match version {
        VERSION_1 => 5,
        VERSION_2 => 1,
        _ => 0,
    }
}
/// Bytes before the payload.
pub const HEADER_LEN: usize = 10;
/// Bytes of the trailing CRC.
pub const CRC_LEN: usize = 4;
/// Most inputs a model may take (4 pixels + 5 joint angles for posture-aware models, with room).
pub const MAX_INPUTS: usize = 12;
/// Most hidden units.
pub const MAX_HIDDEN: usize = 32;
/// Most outputs (X, Y, Z).
pub const MAX_OUTPUTS: usize = 3;
/// Most parameters of the largest topology, linear skip weights included.
pub const MAX_PARAMS: usize = mlp::param_count(MAX_INPUTS, MAX_HIDDEN, MAX_OUTPUTS)
    + mlp::skip_count(MAX_INPUTS, MAX_OUTPUTS);
/// Largest payload accepted.
pub const MAX_PAYLOAD_LEN: usize = 4096 - HEADER_LEN - CRC_LEN;
/// Largest blob, header and CRC included: a buffer this big holds any valid blob.
pub const MAX_BLOB_LEN: usize = HEADER_LEN + MAX_PAYLOAD_LEN + CRC_LEN;

// Table-less: 1 KiB less flash on the head; the blob is checked once per boot.
const CRC32: crc::Crc<u32, crc::NoTable> =
    crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

/// CRC-32 (ISO-HDLC, the zlib/PNG one) of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// Why bytes are not a usable blob.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum BlobError {
    /// The first four bytes are not [`MAGIC`] (e.g. an erased slot).
    BadMagic,
    /// A format version this build does not read.
    UnsupportedVersion(u16),
    /// Fewer bytes than the header announces.
    Truncated,
    /// The payload length is larger than [`MAX_PAYLOAD_LEN`].
    TooLarge,
    /// The CRC does not match: the blob was damaged.
    BadCrc,
    /// The CRC matches but the payload is not a valid postcard `ModelBlob`.
    Malformed,
    /// Sizes in the payload contradict each other, exceed the limits, or differ from the
    /// topology the caller asked for.
    TopologyMismatch,
    /// A parameter is NaN or infinite, or a scale is zero.
    BadParameter,
    /// The output buffer is too small to encode into.
    BufferTooSmall,
}

impl core::fmt::Display for BlobError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            BlobError::BadMagic => f.write_str("not an hvs weights blob (bad magic)"),
            BlobError::UnsupportedVersion(v) => write!(
                f,
                "unsupported blob format version {v} (this build reads versions {VERSION_1} to {VERSION})"
            ),
            BlobError::Truncated => f.write_str("blob is truncated"),
            BlobError::TooLarge => f.write_str("blob payload length exceeds the maximum"),
            BlobError::BadCrc => f.write_str("blob CRC mismatch (damaged)"),
            BlobError::Malformed => f.write_str("blob payload is malformed"),
            BlobError::TopologyMismatch => {
                f.write_str("blob topology is inconsistent or not the one expected")
            }
            BlobError::BadParameter => {
                f.write_str("blob holds a non-finite parameter or a zero scale")
            }
            BlobError::BufferTooSmall => f.write_str("output buffer too small"),
        }
    }
}

/// What a model's inputs are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum InputKind {
    /// `u_l, v_l, u_r, v_r` in pixels (the thesis' net).
    Stereo,
    /// `u_l, v_l, u_r, v_r` then the five joint angles in degrees (neck pan, neck tilt,
    /// eye tilt, left eye pan, right eye pan).
    StereoJoints,
}

impl InputKind {
    /// Number of inputs of this kind.
    pub const fn len(self) -> usize {
        match self {
            InputKind::Stereo => 4,
            InputKind::StereoJoints => 9,
        }
    }
    /// Never empty; present for API symmetry with `len`.
    pub const fn is_empty(self) -> bool {
        false
    }
}

/// What a model's outputs are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum OutputKind {
    /// `X, Y, Z` in cm.
    Xyz,
    /// `Z` only, in cm.
    Z,
}

impl OutputKind {
    /// Number of outputs of this kind.
    pub const fn len(self) -> usize {
        match self {
            OutputKind::Xyz => 3,
            OutputKind::Z => 1,
        }
    }
    /// Never empty; present for API symmetry with `len`.
    pub const fn is_empty(self) -> bool {
        false
    }
}

/// Network shape. The hidden activation is always the sigmoid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Topology {
    /// What the inputs are (their count follows).
    pub inputs: InputKind,
    /// Hidden units, 1..=[`MAX_HIDDEN`].
    pub hidden: u8,
    /// What the outputs are (their count follows).
    pub outputs: OutputKind,
    /// Output activation.
    pub output_activation: Activation,
}

/// Which training algorithm produced a model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Algorithm {
    /// Levenberg-Marquardt.
    Lm,
    /// The thesis' per-pattern back-propagation.
    Bp,
    /// Adam.
    Adam,
    /// Anything else (e.g. hand-built in a test).
    Other,
}

/// How the model was trained: enough to reproduce it and to judge it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrainingMeta {
    /// Seed of the training run.
    pub seed: u64,
    /// Hash of the training set (FNV-1a 64 over its rows).
    pub train_hash: u64,
    /// Number of training points.
    pub train_points: u32,
    /// Training e_ma in percent, computed with this f32 model.
    pub train_error_pct: f32,
    /// Algorithm.
    pub algorithm: Algorithm,
    /// Restarts tried.
    pub restarts: u16,
}

/// Which `exp` the sigmoid uses. Extensible: a faster approximation for the firmware would be
/// a new variant (new models only; every variant must give the same bits on host and head).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ExpKind {
    /// The exp of [`mlp::sigmoid`], what every model so far uses: `libm::expf` (libm 0.2)
    /// in earlier versions of hvs, now the range-reduced polynomial [`mlp::exp`] (within 8.2e-8 of
    /// `e^x`; predictions moved by an ulp or so, the variant and the bytes stayed).
    LibmExp,
}

impl ExpKind {
    /// What the sigmoid's `exp` is, for people (`hvs info`).
    pub fn name(self) -> &'static str {
        match self {
            ExpKind::LibmExp => "mlp::exp, a range-reduced polynomial within 8.2e-8 of e^x",
        }
    }
}

/// Whether the net has a linear skip term (inputs straight to outputs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Skip {
    /// The sigmoid net alone.
    None,
    /// Each output also gets `sum_i s[k][i] xn[i]` over the normalised inputs
    /// ([`crate::runtime::mlp`] documents the layout and order): the sigmoid layer learns a
    /// residual over an affine map of the pixels. With inverse-depth outputs the affine part
    /// alone is exact for parallel pinhole cameras.
    Linear,
}

/// The model family: what the net's outputs mean and how its activation is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Family {
    /// How the de-normalised outputs become cm.
    pub output_map: OutputMap,
    /// The sigmoid's exp.
    pub exp: ExpKind,
    /// Linear skip term or not.
    pub skip: Skip,
}

impl Family {
    /// The thesis' net: `X, Y, Z` outputs, libm exp (every version-1 blob).
    pub const THESIS: Family =
        Family { output_map: OutputMap::Direct, exp: ExpKind::LibmExp, skip: Skip::None };
    /// Inverse-depth outputs `X/Z, Y/Z, 1/Z`, libm exp.
    pub const INVERSE_DEPTH: Family =
        Family { output_map: OutputMap::InverseDepth, exp: ExpKind::LibmExp, skip: Skip::None };
    /// Inverse-depth outputs over an affine map of the pixels plus the sigmoid net's residual
    /// ([`Skip::Linear`]), libm exp.
    pub const INVERSE_DEPTH_SKIP: Family =
        Family { output_map: OutputMap::InverseDepth, exp: ExpKind::LibmExp, skip: Skip::Linear };
    /// Short name (`thesis`, `inverse-depth`, `inverse-depth-skip`; `direct-skip` for X, Y, Z
    /// outputs with a skip term), as `hvs train --arch` takes it.
    pub fn name(&self) -> &'static str {
        match (self.output_map, self.skip) {
            (OutputMap::Direct, Skip::None) => "thesis",
            (OutputMap::InverseDepth, Skip::None) => "inverse-depth",
            (OutputMap::InverseDepth, Skip::Linear) => "inverse-depth-skip",
            (OutputMap::Direct, Skip::Linear) => "direct-skip",
        }
    }
    /// Skip weights of a net with `i` inputs and `o` outputs in this family.
    pub const fn skip_len(&self, i: usize, o: usize) -> usize {
        match self.skip {
            Skip::None => 0,
            Skip::Linear => mlp::skip_count(i, o),
        }
    }
}

/// The frame a model's `X, Y, Z` are in before [`ModelBlob::infer`] hands them out (always
/// in the head frame, the base frame of [`crate::runtime::gaze`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum OutputFrame {
    /// The net gives head-frame points (every version-1 and -2 blob; every stereo model).
    Head,
    /// A posture-aware net gives points in the eye platform's frame: the head frame turned by
    /// the neck pan, neck tilt and eye tilt of its joint inputs (inputs 5-7, degrees) about the
    /// baseline's centre. The inference turns them into the head frame
    /// ([`gaze::platform_to_base`], f32, the same bits on host and head). Those three
    /// joints turn both cameras together, so in this frame the pixels-to-point map barely
    /// depends on them and the net is left with the eye pans (vergence, version) and whatever
    /// the nominal chain misses (a neck centre off the baseline, axis errors), which the joint
    /// inputs still let it learn. Only for [`InputKind::StereoJoints`] inputs and
    /// [`OutputKind::Xyz`] outputs.
    EyePlatform,
    /// A posture-aware net gives points in the cyclopean frame: the eye platform's frame
    /// turned by the version (the mean of the eye pans, inputs 8 and 9) about its vertical
    /// axis through the baseline's centre ([`gaze::cyclopean_to_base`], f32, the same bits on
    /// host and head). In this frame each eye is turned from straight ahead by half the
    /// vergence only, so the pixels-to-point map bends far less with the eye pans than in
    /// the eye platform's frame: what a net needs on sets where the board is seen anywhere in
    /// the images (`hvs collect`: the board stays, the head moves). Only for
    /// [`InputKind::StereoJoints`] inputs and [`OutputKind::Xyz`] outputs.
    Cyclopean,
}

impl OutputFrame {
    /// Turns the outputs `y` (cm, in this frame) of inputs `x` into the head frame, in place.
    #[inline]
    pub fn apply(self, x: &[f32], y: &mut [f32]) -> Result<(), MlpError> {
        match self {
            OutputFrame::Head => Ok(()),
            OutputFrame::EyePlatform | OutputFrame::Cyclopean => {
                let (Some(j), [a, b, c]) = (x.get(4..9), &mut *y) else {
                    return Err(MlpError::Shape);
                };
                let p =
                    gaze::posture_to_base([j[0], j[1], j[2]], self.version_deg(j), [*a, *b, *c]);
                if !p.iter().all(|v| v.is_finite()) {
                    return Err(MlpError::NonFiniteOutput);
                }
                [*a, *b, *c] = p;
                Ok(())
            }
        }
    }

    /// The inverse of [`OutputFrame::apply`]: head-frame `y` of inputs `x` in this frame
    /// (unchanged for [`OutputFrame::Head`], and for inputs without joint angles).
    pub fn from_head(self, x: &[f32], y: [f32; 3]) -> [f32; 3] {
        match (self, x.get(4..9)) {
            (OutputFrame::EyePlatform | OutputFrame::Cyclopean, Some(j)) => {
                gaze::base_to_posture([j[0], j[1], j[2]], self.version_deg(j), y)
            }
            _ => y,
        }
    }

    /// How far this frame is turned about the eye platform's vertical axis at joint inputs
    /// `j` (neck pan .. right eye pan, degrees): the version for [`OutputFrame::Cyclopean`],
    /// 0 otherwise.
    fn version_deg(self, j: &[f32]) -> f32 {
        match (self, j) {
            (OutputFrame::Cyclopean, [_, _, _, l, r, ..]) => gaze::version_deg(*l, *r),
            _ => 0.0,
        }
    }

    /// Short name (`head`, `eye-platform`, `cyclopean`), as `hvs train --frame` takes it.
    pub fn name(self) -> &'static str {
        match self {
            OutputFrame::Head => "head",
            OutputFrame::EyePlatform => "eye-platform",
            OutputFrame::Cyclopean => "cyclopean",
        }
    }
}

/// Geometry for the run-time stereo matcher, fitted to the training correspondences (the
/// fitting lives with the matcher, not here).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MatcherGeometry {
    /// Fundamental matrix `F` with `[u_r, v_r, 1] F [u_l, v_l, 1]^T = 0` for a matched pair,
    /// scaled so that its largest entry is 1 (`f32`: no `f64` decoding on the head).
    pub fundamental: [[f32; 3]; 3],
    /// Smallest `X, Y, Z` (cm) of the training targets; `out_min[2]..out_max[2]` is the depth
    /// range the matcher searches.
    pub out_min: [f32; 3],
    /// Largest `X, Y, Z` (cm) of the training targets.
    pub out_max: [f32; 3],
    /// Smallest and largest disparity `u_l - u_r` (px) of the training pixels.
    pub disparity: [f32; 2],
    /// How much larger the right image shows a patch than the left one, along `u` and `v`
    /// (the ratio of the two cameras' image scales, read off the training set).
    pub right_scale: [f32; 2],
}

impl MatcherGeometry {
    /// Finite entries, a non-empty box.
    pub fn is_valid(&self) -> bool {
        self.fundamental.iter().flatten().all(|v| v.is_finite())
            && self
                .out_min
                .iter()
                .zip(&self.out_max)
                .all(|(lo, hi)| lo.is_finite() && hi.is_finite() && lo <= hi)
            && self.disparity.iter().all(|d| d.is_finite())
            && self.disparity[0] <= self.disparity[1]
            && self.right_scale.iter().all(|s| s.is_finite() && *s > 0.0)
    }
}

/// The size in pixels of the images a model was trained on (every image of a capture set has
/// it): a pair of another size does not fit the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ImageSize {
    /// Width in pixels.
    pub width: u16,
    /// Height in pixels.
    pub height: u16,
}

/// The model a model was updated from: its blob's CRC-32 (the 4 bytes after its payload) and
/// its generation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Parent {
    /// The parent blob's CRC-32.
    pub crc: u32,
    /// The parent's generation.
    pub generation: u32,
}

impl Parent {
    /// The parent record of the valid blob at the start of `bytes` (decoded and checked).
    pub fn of(bytes: &[u8]) -> Result<Parent, BlobError> {
        let b = decode(bytes)?;
        let end = framed_len(bytes)?;
        let crc =
            u32::from_le_bytes([bytes[end - 4], bytes[end - 3], bytes[end - 2], bytes[end - 1]]);
        Ok(Parent { crc, generation: b.generation })
    }
}

/// A model as stored: the decoded payload of a blob.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelBlob {
    /// Generation number: among valid slots, the head runs the highest.
    pub generation: u32,
    /// Shape.
    pub topology: Topology,
    /// Input offsets (one per input).
    pub in_offset: Vec<f32, MAX_INPUTS>,
    /// Input scales.
    pub in_scale: Vec<f32, MAX_INPUTS>,
    /// Output offsets (one per output).
    pub out_offset: Vec<f32, MAX_OUTPUTS>,
    /// Output scales.
    pub out_scale: Vec<f32, MAX_OUTPUTS>,
    /// Parameters in the layout documented in [`crate::runtime::mlp`]: the sigmoid net's,
    /// then the skip weights if the family has them.
    pub params: Vec<f32, MAX_PARAMS>,
    /// Smallest value of each input seen in training.
    pub in_min: Vec<f32, MAX_INPUTS>,
    /// Largest value of each input seen in training.
    pub in_max: Vec<f32, MAX_INPUTS>,
    /// Training metadata.
    pub meta: TrainingMeta,
    /// The traditional method's calibration fitted on the same data (eq. 4.1-3), if the data
    /// allowed it.
    pub fallback: Option<Calibration>,
    /// The model family (format version 2; [`Family::THESIS`] for a version-1 blob).
    pub family: Family,
    /// Stereo-matcher geometry, if fitted (format version 2; `None` for a version-1 blob).
    pub matcher: Option<MatcherGeometry>,
    /// The frame of the net's points (format version 3; [`OutputFrame::Head`] for older
    /// blobs).
    pub frame: OutputFrame,
    /// The size of the training images (format version 4; `None` for a model trained from
    /// points without images, and for older blobs). Encoded by hand, after the serde fields.
    #[serde(skip)]
    pub image_size: Option<ImageSize>,
    /// The model this one was updated from (format version 4; `None` for a model trained
    /// from scratch, and for older blobs). Encoded by hand, last.
    #[serde(skip)]
    pub parent: Option<Parent>,
}

impl ModelBlob {
    /// Number of inputs.
    pub fn n_inputs(&self) -> usize {
        self.topology.inputs.len()
    }
    /// Number of outputs.
    pub fn n_outputs(&self) -> usize {
        self.topology.outputs.len()
    }

    /// Checks sizes against the topology and the limits, and parameter values.
    pub fn validate(&self) -> Result<(), BlobError> {
        let (i, o) = (self.n_inputs(), self.n_outputs());
        let h = self.topology.hidden as usize;
        if h == 0
            || h > MAX_HIDDEN
            || h > mlp::FLAT_MAX_HIDDEN
            || i > MAX_INPUTS
            || self.in_offset.len() != i
            || self.in_scale.len() != i
            || self.in_min.len() != i
            || self.in_max.len() != i
            || self.out_offset.len() != o
            || self.out_scale.len() != o
            || self.params.len() != mlp::param_count(i, h, o) + self.family.skip_len(i, o)
            || (self.frame != OutputFrame::Head
                && (self.topology.inputs != InputKind::StereoJoints
                    || self.topology.outputs != OutputKind::Xyz))
        {
            return Err(BlobError::TopologyMismatch);
        }
        let finite = |s: &[f32]| s.iter().all(|v| v.is_finite());
        let nonzero = |s: &[f32]| s.iter().all(|v| *v != 0.0);
        if !(finite(&self.params)
            && finite(&self.in_offset)
            && finite(&self.in_scale)
            && finite(&self.out_offset)
            && finite(&self.out_scale)
            && finite(&self.in_min)
            && finite(&self.in_max)
            && nonzero(&self.in_scale)
            && nonzero(&self.out_scale)
            && self.meta.train_error_pct.is_finite())
        {
            return Err(BlobError::BadParameter);
        }
        if let Some(c) = &self.fallback {
            if !c.is_valid() {
                return Err(BlobError::BadParameter);
            }
        }
        if let Some(m) = &self.matcher {
            if !m.is_valid() {
                return Err(BlobError::BadParameter);
            }
        }
        Ok(())
    }

    /// A runtime-sized view for [`mlp::infer_flat`].
    pub fn flat(&self) -> FlatMlp<'_> {
        let n = self
            .params
            .len()
            .saturating_sub(self.family.skip_len(self.n_inputs(), self.n_outputs()));
        FlatMlp {
            hidden: self.topology.hidden as usize,
            params: &self.params[..n],
            skip: &self.params[n..],
            output: self.topology.output_activation,
            in_offset: &self.in_offset,
            in_scale: &self.in_scale,
            out_offset: &self.out_offset,
            out_scale: &self.out_scale,
        }
    }

    /// Inference with whatever topology the blob holds, in cm in the head frame:
    /// [`mlp::infer_flat`] (same bits as [`Mlp::infer`]), the family's [`OutputMap`], then
    /// the [`OutputFrame`].
    pub fn infer(&self, x: &[f32], out: &mut [f32]) -> Result<(), MlpError> {
        mlp::infer_flat(&self.flat(), x, out)?;
        self.finish(x, out)
    }

    /// What follows the net in [`ModelBlob::infer`]: the family's [`OutputMap`], then the
    /// [`OutputFrame`] (which reads the joint inputs of `x`). The head's fast path ends with it
    /// too.
    #[inline]
    pub fn finish(&self, x: &[f32], out: &mut [f32]) -> Result<(), MlpError> {
        self.family.output_map.apply(out)?;
        self.frame.apply(x, out)
    }

    /// The training images' size as `(width, height)` pixels, if the model was trained from
    /// images.
    pub fn image_size(&self) -> Option<(u16, u16)> {
        self.image_size.map(|s| (s.width, s.height))
    }

    /// Records the training images' size (`None`: trained from points without images).
    pub fn set_image_size(&mut self, size: Option<(u16, u16)>) {
        self.image_size = size.map(|(width, height)| ImageSize { width, height });
    }

    /// The `(crc, generation)` of the model this one was updated from, if any.
    pub fn parent(&self) -> Option<(u32, u32)> {
        self.parent.map(|p| (p.crc, p.generation))
    }

    /// Records the parent model (`None`: trained from scratch).
    pub fn set_parent(&mut self, parent: Option<Parent>) {
        self.parent = parent;
    }

    /// Whether every input lies inside the box seen in training.
    pub fn in_range(&self, x: &[f32]) -> bool {
        x.len() == self.in_min.len()
            && x.iter()
                .zip(self.in_min.iter().zip(self.in_max.iter()))
                .all(|(v, (lo, hi))| *v >= *lo && *v <= *hi)
    }

    /// The model as a fixed-size [`Mlp`], if its topology is exactly `I-H-O` and it has no
    /// skip term (an [`Mlp`] has none). The [`Mlp`] stops at the de-normalised outputs: apply
    /// `self.family.output_map` to get cm.
    pub fn to_mlp<const I: usize, const H: usize, const O: usize>(
        &self,
    ) -> Result<Mlp<I, H, O>, BlobError> {
        if self.n_inputs() != I
            || self.topology.hidden as usize != H
            || self.n_outputs() != O
            || self.family.skip != Skip::None
        {
            return Err(BlobError::TopologyMismatch);
        }
        let arr = |s: &[f32]| -> Result<[f32; I], BlobError> {
            s.try_into().map_err(|_| BlobError::TopologyMismatch)
        };
        let arr_o = |s: &[f32]| -> Result<[f32; O], BlobError> {
            s.try_into().map_err(|_| BlobError::TopologyMismatch)
        };
        Mlp::from_params(
            &self.params,
            self.topology.output_activation,
            arr(&self.in_offset)?,
            arr(&self.in_scale)?,
            arr_o(&self.out_offset)?,
            arr_o(&self.out_scale)?,
        )
        .map_err(|_| BlobError::TopologyMismatch)
    }

    /// Writes the blob (header, postcard payload, CRC) into `buf`; returns its length.
    pub fn encode(&self, buf: &mut [u8]) -> Result<usize, BlobError> {
        self.validate()?;
        if buf.len() < HEADER_LEN + CRC_LEN {
            return Err(BlobError::BufferTooSmall);
        }
        let limit = core::cmp::min(buf.len() - CRC_LEN, HEADER_LEN + MAX_PAYLOAD_LEN);
        let n = postcard::to_slice(self, &mut buf[HEADER_LEN..limit])
            .map_err(|_| BlobError::BufferTooSmall)?
            .len();
        let n = n + write_v4_fields(self, &mut buf[HEADER_LEN + n..limit])?;
        buf[0..4].copy_from_slice(&MAGIC);
        buf[4..6].copy_from_slice(&VERSION.to_le_bytes());
        buf[6..10].copy_from_slice(&(n as u32).to_le_bytes());
        let crc = crc32(&buf[..HEADER_LEN + n]);
        buf[HEADER_LEN + n..HEADER_LEN + n + CRC_LEN].copy_from_slice(&crc.to_le_bytes());
        Ok(HEADER_LEN + n + CRC_LEN)
    }
}

/// Length of the blob at the start of `bytes` according to its header (header, payload, CRC),
/// after checking magic, version and the length limit, but not the CRC.
pub fn framed_len(bytes: &[u8]) -> Result<usize, BlobError> {
    if bytes.len() < 4 {
        return Err(if MAGIC.starts_with(bytes) {
            BlobError::Truncated
        } else {
            BlobError::BadMagic
        });
    }
    if bytes[0..4] != MAGIC {
        return Err(BlobError::BadMagic);
    }
    if bytes.len() < HEADER_LEN {
        return Err(BlobError::Truncated);
    }
    let version = u16::from_le_bytes([bytes[4], bytes[5]]);
    if !(VERSION_1..=VERSION).contains(&version) {
        return Err(BlobError::UnsupportedVersion(version));
    }
    let n = u32::from_le_bytes([bytes[6], bytes[7], bytes[8], bytes[9]]) as usize;
    if n > MAX_PAYLOAD_LEN {
        return Err(BlobError::TooLarge);
    }
    Ok(HEADER_LEN + n + CRC_LEN)
}

/// Decodes and validates the blob at the start of `bytes` (trailing bytes are ignored).
pub fn decode(bytes: &[u8]) -> Result<ModelBlob, BlobError> {
    let mut blob = placeholder();
    decode_into(bytes, &mut blob)?;
    Ok(blob)
}

/// [`decode`] into an existing blob, for the head's boot: the same checks in the same order
/// (header, length, CRC, postcard payload with nothing left over, [`ModelBlob::validate`]),
/// but the payload is deserialized field by field into `out` (serde's
/// `deserialize_in_place`) instead of being built on the stack and moved out through several
/// frames: on the Cortex-M4F this keeps boot's stack at a few KB (`firmware/measure.sh`
/// reports the measured peak). `Ok` leaves exactly what [`decode`] returns in `out`; on `Err`,
/// `out` holds some partly decoded blob that must not be used.
pub fn decode_into(bytes: &[u8], out: &mut ModelBlob) -> Result<(), BlobError> {
    let total = framed_len(bytes)?;
    if bytes.len() < total {
        return Err(BlobError::Truncated);
    }
    let body = total - CRC_LEN;
    let stored =
        u32::from_le_bytes([bytes[body], bytes[body + 1], bytes[body + 2], bytes[body + 3]]);
    if crc32(&bytes[..body]) != stored {
        return Err(BlobError::BadCrc);
    }
    let payload = &bytes[HEADER_LEN..body];
    let version = u16::from_le_bytes([bytes[4], bytes[5]]);
    match tail_len(version) {
        0 => {
            let rest = payload_into(payload, out)?;
            if version == VERSION {
                read_v4_fields(rest, out)?;
            } else if !rest.is_empty() {
                return Err(BlobError::Malformed);
            }
        }
        tail => decode_old_payload_into(payload, tail, out)?,
    }
    out.validate()
}

/// Writes [`ModelBlob::image_size`] and [`ModelBlob::parent`] as postcard would (a `0`/`1`
/// option byte, then the fields as LEB128 varints) into `buf`; returns the bytes written.
fn write_v4_fields(b: &ModelBlob, buf: &mut [u8]) -> Result<usize, BlobError> {
    let mut tmp = [0u8; 1 + 2 * 3 + 1 + 2 * 5];
    let mut n = 0;
    let mut put = |v: u32, tmp: &mut [u8]| {
        let mut v = v;
        while v >= 0x80 {
            tmp[n] = (v as u8) | 0x80;
            v >>= 7;
            n += 1;
        }
        tmp[n] = v as u8;
        n += 1;
    };
    match b.image_size {
        Some(s) => {
            put(1, &mut tmp);
            put(s.width.into(), &mut tmp);
            put(s.height.into(), &mut tmp);
        }
        None => put(0, &mut tmp),
    }
    match b.parent {
        Some(p) => {
            put(1, &mut tmp);
            put(p.crc, &mut tmp);
            put(p.generation, &mut tmp);
        }
        None => put(0, &mut tmp),
    }
    buf.get_mut(..n).ok_or(BlobError::BufferTooSmall)?.copy_from_slice(&tmp[..n]);
    Ok(n)
}

/// Reads what [`write_v4_fields`] writes, accepting exactly what postcard's decoder of
/// `(Option<ImageSize>, Option<Parent>)` accepts, and nothing after it.
fn read_v4_fields(bytes: &[u8], out: &mut ModelBlob) -> Result<(), BlobError> {
    let mut at = Bytes(bytes);
    out.image_size = None;
    out.parent = None;
    if at.some()? {
        let width = at.varint(16)? as u16;
        let height = at.varint(16)? as u16;
        out.image_size = Some(ImageSize { width, height });
    }
    if at.some()? {
        let crc = at.varint(32)?;
        let generation = at.varint(32)?;
        out.parent = Some(Parent { crc, generation });
    }
    if at.0.is_empty() {
        Ok(())
    } else {
        Err(BlobError::Malformed)
    }
}

/// The bytes of [`read_v4_fields`] not read yet.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn byte(&mut self) -> Result<u8, BlobError> {
        let (&b, rest) = self.0.split_first().ok_or(BlobError::Malformed)?;
        self.0 = rest;
        Ok(b)
    }

    /// A postcard option tag.
    fn some(&mut self) -> Result<bool, BlobError> {
        match self.byte()? {
            0 => Ok(false),
            1 => Ok(true),
            _ => Err(BlobError::Malformed),
        }
    }

    /// A postcard varint of a `bits`-bit unsigned integer (16 or 32): at most 3 or 5 bytes,
    /// nothing above the top bit. One copy for every field (the head's flash).
    #[inline(never)]
    fn varint(&mut self, bits: u32) -> Result<u32, BlobError> {
        let (mut v, mut shift) = (0u32, 0u32);
        loop {
            let b = self.byte()?;
            let part = u32::from(b & 0x7F);
            if shift > 0 && part >> (bits - shift) != 0 {
                return Err(BlobError::Malformed);
            }
            v |= part << shift;
            if b & 0x80 == 0 {
                return Ok(v);
            }
            shift += 7;
            if shift >= bits {
                return Err(BlobError::Malformed);
            }
        }
    }
}

/// An older payload is the current one without the fields its version lacks: it is read
/// with the last `tail` bytes of [`TAIL`] (their defaults' encoding) appended. Kept out of
/// line, so the widened copy is on the stack only while an old blob is read.
#[inline(never)]
fn decode_old_payload_into(
    payload: &[u8],
    tail: usize,
    out: &mut ModelBlob,
) -> Result<(), BlobError> {
    let mut widened = [0u8; MAX_PAYLOAD_LEN + TAIL.len()];
    let n = payload.len() + tail;
    widened[..payload.len()].copy_from_slice(payload);
    let rest = payload_into(&widened[..n], out)?;
    // An old payload with bytes after its last field could have read them as a newer field:
    // it is malformed. (A version-2 payload may hold any family and matcher.)
    let v1_fields =
        tail < tail_len(VERSION_1) || (out.family == Family::THESIS && out.matcher.is_none());
    if !rest.is_empty() || !v1_fields || out.frame != OutputFrame::Head {
        return Err(BlobError::Malformed);
    }
    Ok(())
}

/// Deserializes the serde fields of `payload` into `out` (the version-4 fields become
/// `None`); returns the bytes after them.
fn payload_into<'a>(payload: &'a [u8], out: &mut ModelBlob) -> Result<&'a [u8], BlobError> {
    let mut de = postcard::Deserializer::from_bytes(payload);
    ModelBlob::deserialize_in_place(&mut de, out).map_err(|_| BlobError::Malformed)?;
    de.finalize().map_err(|_| BlobError::Malformed)
}

/// A blob with no parameters (it does not validate): a place to [`decode_into`].
pub fn placeholder() -> ModelBlob {
    ModelBlob {
        generation: 0,
        topology: Topology {
            inputs: InputKind::Stereo,
            hidden: 0,
            outputs: OutputKind::Xyz,
            output_activation: Activation::Linear,
        },
        in_offset: Vec::new(),
        in_scale: Vec::new(),
        out_offset: Vec::new(),
        out_scale: Vec::new(),
        params: Vec::new(),
        in_min: Vec::new(),
        in_max: Vec::new(),
        meta: TrainingMeta {
            seed: 0,
            train_hash: 0,
            train_points: 0,
            train_error_pct: 0.0,
            algorithm: Algorithm::Other,
            restarts: 0,
        },
        fallback: None,
        family: Family::THESIS,
        matcher: None,
        frame: OutputFrame::Head,
        image_size: None,
        parent: None,
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use proptest::prelude::*;
    use std::vec::Vec as StdVec;

    pub(crate) fn sample(hidden: u8, seed: u32) -> ModelBlob {
        let mut params = Vec::new();
        for k in 0..mlp::param_count(4, hidden as usize, 3) {
            params
                .push(
                    ((k as u32).wrapping_mul(2654435761).wrapping_add(seed) % 2000) as f32 / 1000.0
                        - 1.0,
                )
                .unwrap();
        }
        ModelBlob {
            generation: 7,
            topology: Topology {
                inputs: InputKind::Stereo,
                hidden,
                outputs: OutputKind::Xyz,
                output_activation: Activation::Linear,
            },
            in_offset: Vec::from_slice(&[320.0, 240.0, 300.0, 240.0]).unwrap(),
            in_scale: Vec::from_slice(&[0.02, 0.05, 0.02, 0.05]).unwrap(),
            out_offset: Vec::from_slice(&[0.0, 0.0, 115.0]).unwrap(),
            out_scale: Vec::from_slice(&[3.0, 2.0, 50.0]).unwrap(),
            params,
            in_min: Vec::from_slice(&[300.0, 220.0, 280.0, 220.0]).unwrap(),
            in_max: Vec::from_slice(&[360.0, 260.0, 330.0, 260.0]).unwrap(),
            meta: TrainingMeta {
                seed: 42,
                train_hash: 0xdead_beef,
                train_points: 72,
                train_error_pct: 0.8,
                algorithm: Algorithm::Lm,
                restarts: 10,
            },
            fallback: Some(Calibration { phi: 285.0, half_baseline: 5.25, u0: 320.0, v0: 240.0 }),
            family: Family::THESIS,
            matcher: None,
            frame: OutputFrame::Head,
            image_size: None,
            parent: None,
        }
    }

    /// A valid matcher geometry.
    const MATCHER: MatcherGeometry = MatcherGeometry {
        fundamental: [[0.0, -1e-5, 2e-3], [1e-5, 0.0, -0.3], [-2e-3, 0.3, 1.0]],
        out_min: [-3.0, -2.0, 65.0],
        out_max: [3.0, 2.0, 165.0],
        disparity: [10.5, 46.0],
        right_scale: [1.25, 1.25],
    };

    /// A point inside [`sample`]'s input box.
    const X: [f32; 4] = [330.0, 235.0, 300.0, 238.0];

    /// A 4-5-3 [`sample`] from `seed` and its outputs at [`X`].
    fn sample_at_x(seed: u32) -> (ModelBlob, [f32; 3]) {
        let b = sample(5, seed);
        let mut y = [0.0f32; 3];
        b.infer(&X, &mut y).unwrap();
        (b, y)
    }

    fn bytes(b: &ModelBlob) -> StdVec<u8> {
        let mut buf = [0u8; MAX_BLOB_LEN];
        let n = b.encode(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    #[test]
    fn round_trip_and_fixed_size_model() {
        let b = sample(5, 1);
        let v = bytes(&b);
        assert_eq!(&v[0..4], b"HVSW");
        let d = decode(&v).unwrap();
        assert_eq!(d, b);
        // Trailing bytes (rest of a flash slot) are ignored.
        let mut slot = v.clone();
        slot.extend_from_slice(&[0xFF; 100]);
        assert_eq!(decode(&slot).unwrap(), b);
        let m: Mlp<4, 5, 3> = d.to_mlp().unwrap();
        let x = X;
        let mut out = [0.0; 3];
        d.infer(&x, &mut out).unwrap();
        assert_eq!(m.infer(&x).unwrap(), out);
        assert_eq!(d.to_mlp::<4, 6, 3>().unwrap_err(), BlobError::TopologyMismatch);
        assert!(d.in_range(&x));
        assert!(!d.in_range(&[10.0, 235.0, 300.0, 238.0]));
    }

    #[test]
    fn old_tails_are_the_encoding_of_the_defaults() {
        let mut buf = [0u8; 16];
        let n = postcard::to_slice(
            &(Family::THESIS, None::<MatcherGeometry>, OutputFrame::Head),
            &mut buf,
        )
        .unwrap()
        .len();
        assert_eq!(buf[..n], TAIL);
        assert_eq!(n, tail_len(VERSION_1));
        let n = postcard::to_slice(&OutputFrame::Head, &mut buf).unwrap().len();
        assert_eq!(n, tail_len(VERSION_2));
        assert_eq!((tail_len(VERSION_3), tail_len(VERSION)), (0, 0));
    }

    /// The postcard encoding of the two version-4 fields.
    fn v4_fields_by_postcard(size: Option<ImageSize>, parent: Option<Parent>) -> StdVec<u8> {
        postcard::to_allocvec(&(size, parent)).unwrap()
    }

    /// What [`read_v4_fields`] makes of `bytes`.
    fn v4_fields_by_hand(bytes: &[u8]) -> Result<(Option<ImageSize>, Option<Parent>), BlobError> {
        let mut b = placeholder();
        read_v4_fields(bytes, &mut b)?;
        Ok((b.image_size, b.parent))
    }

    #[test]
    fn v4_fields_by_hand_are_postcard_bytes() {
        let cases = [
            (None, None),
            (Some(ImageSize { width: 640, height: 480 }), None),
            (None, Some(Parent { crc: u32::MAX, generation: 0 })),
            (
                Some(ImageSize { width: u16::MAX, height: 0 }),
                Some(Parent { crc: 0x89ab_cdef, generation: 127 }),
            ),
        ];
        for (size, parent) in cases {
            let mut b = sample(5, 1);
            b.image_size = size;
            b.parent = parent;
            let mut buf = [0u8; 32];
            let n = write_v4_fields(&b, &mut buf).unwrap();
            assert_eq!(buf[..n], v4_fields_by_postcard(size, parent)[..]);
            assert_eq!(v4_fields_by_hand(&buf[..n]), Ok((size, parent)));
            assert_eq!(write_v4_fields(&b, &mut buf[..n - 1]), Err(BlobError::BufferTooSmall));
        }
    }

    /// The framing of `b` as format `version` (1, 2 or 3): the current payload minus the tail
    /// that version lacks (`b` must hold its defaults), fresh CRC.
    fn as_old(b: &ModelBlob, version: u16) -> StdVec<u8> {
        // The serde fields it lacks, and the two `None` bytes of the version-4 fields.
        let tail = tail_len(version) + 2;
        let now = bytes(b);
        let n = now.len() - HEADER_LEN - CRC_LEN - tail;
        let mut v = StdVec::from(&now[..HEADER_LEN + n]);
        v[4..6].copy_from_slice(&version.to_le_bytes());
        v[6..10].copy_from_slice(&(n as u32).to_le_bytes());
        let crc = crc32(&v);
        v.extend_from_slice(&crc.to_le_bytes());
        v
    }

    fn as_v1(b: &ModelBlob) -> StdVec<u8> {
        as_old(b, VERSION_1)
    }

    /// `v` with `extra` bytes appended to its payload (length and CRC fixed).
    fn with_extra(v: &[u8], extra: &[u8]) -> StdVec<u8> {
        let mut out = StdVec::from(&v[..v.len() - CRC_LEN]);
        let n = out.len() - HEADER_LEN + extra.len();
        out[6..10].copy_from_slice(&(n as u32).to_le_bytes());
        out.extend_from_slice(extra);
        let crc = crc32(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    #[test]
    fn version_2_decodes_in_the_head_frame_with_its_family_and_matcher() {
        let mut b = sample(5, 9);
        b.family = Family::INVERSE_DEPTH_SKIP;
        b.params.extend_from_slice(&[0.01; 12]).expect("room for the skip weights");
        b.matcher = Some(MATCHER);
        let v2 = as_old(&b, VERSION_2);
        assert_eq!(u16::from_le_bytes([v2[4], v2[5]]), 2);
        assert_eq!(decode(&v2).unwrap(), b);
        // A byte after a v2 payload's last field (which would read as a frame) is malformed.
        assert_eq!(decode(&with_extra(&v2, &[1])), Err(BlobError::Malformed));
        assert_eq!(decode(&with_extra(&v2, &[0])), Err(BlobError::Malformed));
    }

    #[test]
    fn version_3_decodes_without_image_size_and_parent_and_v4_keeps_them() {
        use crate::test_support::SampleSpec;
        let b = SampleSpec::THESIS
            .inputs(InputKind::StereoJoints)
            .hidden(6)
            .family(Family::INVERSE_DEPTH_SKIP)
            .frame(OutputFrame::EyePlatform)
            .build();
        let v3 = as_old(&b, VERSION_3);
        assert_eq!(u16::from_le_bytes([v3[4], v3[5]]), 3);
        let d = decode(&v3).unwrap();
        assert_eq!(d, b);
        assert_eq!((d.image_size(), d.parent()), (None, None));
        // Bytes after a v3 payload's last field (which would read as an image size) are
        // malformed, zeros or not.
        for extra in [&[0u8][..], &[1, 128, 5, 224, 3], &[0, 1, 7, 2]] {
            assert_eq!(decode(&with_extra(&v3, extra)), Err(BlobError::Malformed));
        }
        // Version 4 stores both, and they are part of the bytes the CRC covers.
        let mut m = b.clone();
        m.set_image_size(Some((640, 480)));
        let parent = Parent::of(&bytes(&b)).unwrap();
        let v = bytes(&b);
        assert_eq!(
            parent,
            Parent {
                crc: u32::from_le_bytes(v[v.len() - 4..].try_into().unwrap()),
                generation: b.generation,
            }
        );
        m.set_parent(Some(parent));
        m.generation = b.generation + 1;
        let w = bytes(&m);
        assert_eq!(u16::from_le_bytes([w[4], w[5]]), VERSION);
        let d = decode(&w).unwrap();
        assert_eq!(d, m);
        assert_eq!(d.image_size(), Some((640, 480)));
        assert_eq!(d.parent(), Some((parent.crc, b.generation)));
        // Postcard varints: `Some` + 640 + 480 (2 bytes each) and `Some` + CRC + generation 2,
        // (parent generation 1) where the two `None` bytes were.
        let crc_len = (32 - parent.crc.leading_zeros()).div_ceil(7).max(1) as usize;
        assert_eq!(w.len(), v.len() + 4 + crc_len + 1);
        assert_eq!(w[w.len() - CRC_LEN - 1], 1, "the parent's generation last");
        // A v3 header on a payload that holds them is malformed.
        let mut as3 = w.clone();
        as3[4..6].copy_from_slice(&VERSION_3.to_le_bytes());
        let crc = crc32(&as3[..as3.len() - CRC_LEN]);
        let k = as3.len() - CRC_LEN;
        as3[k..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(decode(&as3), Err(BlobError::Malformed));
        assert_eq!(Parent::of(&v3[..v3.len() - 1]), Err(BlobError::Truncated));
    }

    /// A posture frame's model gives `turn(inputs, the head-frame model's point)`, turns back
    /// through `from_head`, and needs joint inputs and X, Y, Z outputs.
    fn check_posture_frame(frame: OutputFrame, turn: impl Fn(&[f32; 9], [f32; 3]) -> [f32; 3]) {
        use crate::test_support::SampleSpec;
        let spec = SampleSpec::THESIS
            .inputs(InputKind::StereoJoints)
            .hidden(6)
            .family(Family::INVERSE_DEPTH_SKIP);
        let head = spec.build();
        let framed = spec.frame(frame).build();
        let v = bytes(&framed);
        assert_eq!(u16::from_le_bytes([v[4], v[5]]), VERSION);
        assert_eq!(decode(&v).unwrap(), framed);
        let x = [340.0, 240.0, 300.0, 241.0, 12.0, -7.5, 4.0, 3.0, 6.0];
        let mut x2 = x;
        x2[7] = -3.0;
        for x in [x, x2] {
            let (mut y_head, mut y) = ([0.0f32; 3], [0.0f32; 3]);
            head.infer(&x, &mut y_head).unwrap();
            framed.infer(&x, &mut y).unwrap();
            assert_eq!(y, turn(&x, y_head), "{x:?}");
            assert_ne!(y, y_head);
            // The turn back (the range check's) undoes it to rounding.
            let back = frame.from_head(&x, y);
            for k in 0..3 {
                assert!((back[k] - y_head[k]).abs() <= 1e-4 * y_head[k].abs().max(1.0));
            }
        }
        // A stereo model or a Z-only model cannot be in a posture frame.
        let mut stereo = sample(5, 2);
        stereo.frame = frame;
        assert_eq!(stereo.validate(), Err(BlobError::TopologyMismatch));
        let z_only = spec.outputs(OutputKind::Z).frame(frame).build();
        assert_eq!(z_only.validate(), Err(BlobError::TopologyMismatch));
        // Too few inputs for the frame is a shape error, not a panic.
        let mut y3 = [1.0f32, 2.0, 3.0];
        assert_eq!(frame.apply(&x[..8], &mut y3), Err(MlpError::Shape));
    }

    #[test]
    fn eye_platform_frame_turns_the_points_by_the_neck_and_eye_tilt() {
        // Only the neck pan, neck tilt and eye tilt turn the frame.
        check_posture_frame(OutputFrame::EyePlatform, |x, y| {
            gaze::platform_to_base([x[4], x[5], x[6]], y)
        });
        assert_eq!(OutputFrame::EyePlatform.name(), "eye-platform");
    }

    #[test]
    fn cyclopean_frame_turns_the_points_by_all_five_joints() {
        check_posture_frame(OutputFrame::Cyclopean, |x, y| {
            gaze::cyclopean_to_base([x[4], x[5], x[6], x[7], x[8]], y)
        });
        assert_eq!(OutputFrame::Cyclopean.name(), "cyclopean");
        // The frame is the last payload field: the third variant, one byte after the second's.
        use crate::test_support::SampleSpec;
        let spec = SampleSpec::THESIS
            .inputs(InputKind::StereoJoints)
            .hidden(6)
            .family(Family::INVERSE_DEPTH_SKIP);
        let (v, w) = (
            bytes(&spec.frame(OutputFrame::Cyclopean).build()),
            bytes(&spec.frame(OutputFrame::EyePlatform).build()),
        );
        assert_eq!(v.len(), w.len());
        let diff: std::vec::Vec<usize> = (0..v.len() - CRC_LEN).filter(|&k| v[k] != w[k]).collect();
        assert_eq!(diff.len(), 1, "{diff:?}");
        assert_eq!((v[diff[0]], w[diff[0]]), (2, 1));
    }

    #[test]
    fn version_1_decodes_as_the_thesis_family_and_v2_keeps_family_and_matcher() {
        let b = sample(5, 4);
        let v1 = as_v1(&b);
        assert_eq!(decode(&v1).unwrap(), b);
        // A v1 payload with anything after its fields is malformed, even if the extra bytes
        // would complete a family or a matcher.
        let mut extra = StdVec::from(&v1[..v1.len() - CRC_LEN]);
        let n = extra.len() - HEADER_LEN + 4;
        extra[6..10].copy_from_slice(&(n as u32).to_le_bytes());
        extra.extend_from_slice(&[1, 0, 0, 0]);
        let crc = crc32(&extra);
        extra.extend_from_slice(&crc.to_le_bytes());
        assert_eq!(decode(&extra), Err(BlobError::Malformed));
        let mut m = b.clone();
        m.family = Family::INVERSE_DEPTH;
        m.matcher = Some(MATCHER);
        let v = bytes(&m);
        assert_eq!(u16::from_le_bytes([v[4], v[5]]), VERSION);
        assert_eq!(decode(&v).unwrap(), m);
        let mut bad = m.clone();
        if let Some(g) = bad.matcher.as_mut() {
            g.out_min[2] = 200.0;
        }
        assert_eq!(bad.encode(&mut [0u8; MAX_BLOB_LEN]), Err(BlobError::BadParameter));
        if let Some(g) = bad.matcher.as_mut() {
            g.out_min[2] = 65.0;
            g.fundamental[1][1] = f32::NAN;
        }
        assert_eq!(bad.encode(&mut [0u8; MAX_BLOB_LEN]), Err(BlobError::BadParameter));
    }

    #[test]
    fn inverse_depth_outputs_become_cm() {
        let (mut b, raw) = sample_at_x(2);
        b.family = Family::INVERSE_DEPTH;
        // Make the last raw output positive: o2 = raw[2] * 1 + offset.
        b.out_offset[2] += 1.0 - raw[2];
        let mut want = [0.0f32; 3];
        mlp::infer_flat(&b.flat(), &X, &mut want).unwrap();
        let w = want[2];
        assert!(w > 0.0);
        let mut out = [0.0f32; 3];
        b.infer(&X, &mut out).unwrap();
        assert_eq!(out, [want[0] / w, want[1] / w, 1.0 / w]);
        // A negative inverse depth is a negative depth; a zero one is refused.
        b.out_offset[2] -= 2.0;
        b.infer(&X, &mut out).unwrap();
        assert!(out[2] < 0.0);
        b.out_offset[2] = 0.0;
        b.out_scale[2] = 0.0;
        b.params[mlp::param_count(4, 5, 3) - 1] = 0.0;
        assert_eq!(b.validate(), Err(BlobError::BadParameter), "zero scale");
        let mut z = [0.5f32, 0.25, 0.0];
        assert_eq!(OutputMap::InverseDepth.apply(&mut z), Err(MlpError::NonFiniteOutput));
    }

    #[test]
    fn skip_family_stores_its_weights_after_the_net_and_adds_them() {
        let (mut b, plain) = sample_at_x(6);
        b.family = Family { output_map: OutputMap::Direct, ..Family::INVERSE_DEPTH_SKIP };
        assert_eq!(b.validate(), Err(BlobError::TopologyMismatch), "no skip weights");
        let skip = [0.5f32, -0.25, 0.125, 1.0, 0.0, 2.0, -1.0, 0.5, 0.75, 0.0, 0.25, -0.5];
        b.params.extend_from_slice(&skip).unwrap();
        assert_eq!(b.validate(), Ok(()));
        assert_eq!(b.flat().params.len(), mlp::param_count(4, 5, 3));
        assert_eq!(b.flat().skip, &skip[..]);
        assert_eq!(b.to_mlp::<4, 5, 3>().unwrap_err(), BlobError::TopologyMismatch);
        let mut out = [0.0f32; 3];
        b.infer(&X, &mut out).unwrap();
        for k in 0..3 {
            // Undo the output scaling of the plain net, add the skip sum, scale again: the
            // same value up to rounding (the exact order is pinned in mlp's tests).
            let a = (plain[k] - b.out_offset[k]) / b.out_scale[k];
            let s: f32 =
                (0..4).map(|i| skip[k * 4 + i] * (X[i] - b.in_offset[i]) * b.in_scale[i]).sum();
            let want = (a + s) * b.out_scale[k] + b.out_offset[k];
            assert!((out[k] - want).abs() < 1e-3 * (1.0 + want.abs()), "{k}");
        }
        // It round-trips, and the family is part of the bytes.
        let v = bytes(&b);
        assert_eq!(decode(&v).unwrap(), b);
        b.family = Family::INVERSE_DEPTH_SKIP;
        assert_ne!(bytes(&b), v);
        assert_eq!(Family::INVERSE_DEPTH_SKIP.name(), "inverse-depth-skip");
    }

    #[test]
    fn largest_topology_fits() {
        let i = InputKind::StereoJoints.len();
        let mut b = sample(5, 0);
        b.topology = Topology {
            inputs: InputKind::StereoJoints,
            hidden: MAX_HIDDEN as u8,
            outputs: OutputKind::Xyz,
            output_activation: Activation::Sigmoid,
        };
        b.params =
            Vec::from_slice(&[0.5; MAX_PARAMS][..mlp::param_count(9, MAX_HIDDEN, 3) + 27]).unwrap();
        b.family = Family::INVERSE_DEPTH_SKIP;
        b.matcher = Some(MatcherGeometry {
            fundamental: [[1.0; 3]; 3],
            out_min: [0.0; 3],
            out_max: [1.0; 3],
            disparity: [1.0; 2],
            right_scale: [1.0; 2],
        });
        for v in [&mut b.in_offset, &mut b.in_scale, &mut b.in_min, &mut b.in_max] {
            v.clear();
            v.extend_from_slice(&[1.0; 9][..i]).unwrap();
        }
        let v = bytes(&b);
        assert!(v.len() <= MAX_BLOB_LEN);
        assert_eq!(decode(&v).unwrap(), b);
    }

    #[test]
    fn distinct_errors() {
        let v = bytes(&sample(5, 3));
        let mut m = v.clone();
        m[0] = b'X';
        assert_eq!(decode(&m), Err(BlobError::BadMagic));
        assert_eq!(decode(&[0u8; 64]), Err(BlobError::BadMagic));
        assert_eq!(decode(&[0xFFu8; 64]), Err(BlobError::BadMagic));
        let mut m = v.clone();
        m[4] = 5;
        assert_eq!(decode(&m), Err(BlobError::UnsupportedVersion(5)));
        m[4] = 0;
        assert_eq!(decode(&m), Err(BlobError::UnsupportedVersion(0)));
        assert_eq!(decode(&v[..v.len() - 1]), Err(BlobError::Truncated));
        assert_eq!(decode(&v[..2]), Err(BlobError::Truncated));
        let mut m = v.clone();
        m[6..10].copy_from_slice(&(MAX_PAYLOAD_LEN as u32 + 1).to_le_bytes());
        assert_eq!(decode(&m), Err(BlobError::TooLarge));
        let mut m = v.clone();
        m[20] ^= 1;
        assert_eq!(decode(&m), Err(BlobError::BadCrc));
        // A payload with a valid CRC but inconsistent sizes.
        let mut b = sample(5, 3);
        b.topology.hidden = 6;
        assert_eq!(b.encode(&mut [0u8; MAX_BLOB_LEN]), Err(BlobError::TopologyMismatch));
        let mut b = sample(5, 3);
        b.params[3] = f32::NAN;
        assert_eq!(b.encode(&mut [0u8; MAX_BLOB_LEN]), Err(BlobError::BadParameter));
        // Garbage payload under a correct header and CRC.
        let mut g = StdVec::from(&v[..HEADER_LEN]);
        g[6..10].copy_from_slice(&3u32.to_le_bytes());
        g.extend_from_slice(&[0xFF, 0xFF, 0xFF]);
        let crc = crc32(&g);
        g.extend_from_slice(&crc.to_le_bytes());
        assert_eq!(decode(&g), Err(BlobError::Malformed));
        assert_eq!(sample(5, 3).encode(&mut [0u8; 20]), Err(BlobError::BufferTooSmall));
    }

    #[test]
    fn every_single_byte_change_and_truncation_is_rejected() {
        let v = bytes(&sample(5, 9));
        for i in 0..v.len() {
            for delta in 1..=255u8 {
                let mut m = v.clone();
                m[i] = m[i].wrapping_add(delta);
                assert!(decode(&m).is_err(), "byte {i} +{delta} accepted");
            }
        }
        for n in 0..v.len() {
            assert!(decode(&v[..n]).is_err(), "truncation to {n} accepted");
        }
    }

    proptest! {
        #[test]
        fn blob_round_trips(hidden in 1u8..=MAX_HIDDEN as u8, seed in any::<u32>(), generation in any::<u32>(), z in any::<bool>()) {
            let mut b = sample(hidden, seed);
            b.generation = generation;
            if z {
                b.topology.outputs = OutputKind::Z;
                b.out_offset.truncate(1);
                b.out_scale.truncate(1);
                b.params.truncate(mlp::param_count(4, hidden as usize, 1));
                b.fallback = None;
            }
            let v = bytes(&b);
            prop_assert_eq!(decode(&v).unwrap(), b);
        }

        #[test]
        fn v4_fields_by_hand_accept_what_postcard_accepts(v in proptest::collection::vec(any::<u8>(), 0..16)) {
            let by_postcard = postcard::take_from_bytes::<(Option<ImageSize>, Option<Parent>)>(&v)
                .ok()
                .filter(|(_, rest)| rest.is_empty())
                .map(|(fields, _)| fields);
            prop_assert_eq!(v4_fields_by_hand(&v).ok(), by_postcard);
        }

        #[test]
        fn random_bytes_never_decode_or_panic(v in proptest::collection::vec(any::<u8>(), 0..300)) {
            prop_assert!(decode(&v).is_err());
        }
    }
}

#[cfg(test)]
mod in_place_tests {
    extern crate std;

    use super::*;
    use crate::runtime::blob;
    use crate::runtime::mlp::param_count;
    use std::vec::Vec as StdVec;

    fn sample(hidden: u8, inputs: InputKind, seed: u64, fallback: bool) -> ModelBlob {
        let n_in = inputs.len();
        let mut b = placeholder();
        b.generation = seed as u32 + 1;
        b.topology = Topology {
            inputs,
            hidden,
            outputs: OutputKind::Xyz,
            output_activation: if seed % 2 == 0 { Activation::Linear } else { Activation::Sigmoid },
        };
        for k in 0..param_count(n_in, hidden as usize, 3) {
            let r = ((k as u64 * 2_654_435_761 + seed) % 2000) as f32 / 1000.0 - 1.0;
            b.params.push(r).unwrap();
        }
        for i in 0..n_in {
            b.in_offset.push(300.0 + i as f32).unwrap();
            b.in_scale.push(0.02 + i as f32 * 0.001).unwrap();
            b.in_min.push(-1.0 - i as f32).unwrap();
            b.in_max.push(600.0 + i as f32).unwrap();
        }
        for k in 0..3 {
            b.out_offset.push(k as f32 * 50.0).unwrap();
            b.out_scale.push(3.0 + k as f32).unwrap();
        }
        b.meta = TrainingMeta {
            seed,
            train_hash: seed.wrapping_mul(0x9e37_79b9_7f4a_7c15),
            train_points: 72,
            train_error_pct: 1.5,
            algorithm: Algorithm::Lm,
            restarts: 3,
        };
        b.fallback = fallback.then_some(Calibration::BUILT_IN);
        b
    }

    fn encode(b: &ModelBlob) -> StdVec<u8> {
        let mut buf = std::vec![0u8; MAX_BLOB_LEN];
        let n = b.encode(&mut buf).unwrap();
        buf.truncate(n);
        buf
    }

    /// Re-frames `payload` with a correct header and CRC (so the payload itself is judged).
    fn frame(payload: &[u8]) -> StdVec<u8> {
        let mut v = StdVec::from(&b"HVSW"[..]);
        v.extend_from_slice(&blob::VERSION.to_le_bytes());
        v.extend_from_slice(&(payload.len() as u32).to_le_bytes());
        v.extend_from_slice(payload);
        let crc = blob::crc32(&v);
        v.extend_from_slice(&crc.to_le_bytes());
        v
    }

    fn agree(bytes: &[u8]) {
        // A dirty place: what a previous slot left there.
        let mut place = sample(7, InputKind::StereoJoints, 99, true);
        let got = decode_into(bytes, &mut place);
        match decode(bytes) {
            Ok(want) => {
                assert_eq!(got, Ok(()));
                assert_eq!(place, want);
            }
            Err(e) => assert_eq!(got, Err(e)),
        }
    }

    #[test]
    fn agrees_with_decode_on_valid_and_broken_blobs() {
        let blobs = [
            sample(5, InputKind::Stereo, 1, true),
            sample(16, InputKind::StereoJoints, 2, false),
            sample(1, InputKind::Stereo, 3, false),
            sample(32, InputKind::StereoJoints, 4, true),
        ];
        let mut cases = 0;
        for b in &blobs {
            let bytes = encode(b);
            agree(&bytes);
            let mut padded = bytes.clone();
            padded.resize(MAX_BLOB_LEN, 0xff);
            agree(&padded);
            // Every truncation and a bit flip in every byte (header, payload, CRC).
            for n in 0..bytes.len() {
                agree(&bytes[..n]);
                let mut flipped = bytes.clone();
                flipped[n] ^= 1 << (n % 8);
                agree(&flipped);
                cases += 2;
            }
            // Payloads with a valid CRC that are not a valid blob: cut short, one byte too
            // many, a length prefix changed.
            let payload = &bytes[HEADER_LEN..bytes.len() - CRC_LEN];
            for n in [1, 7, payload.len() / 2, payload.len() - 1] {
                agree(&frame(&payload[..n]));
            }
            let mut long = StdVec::from(payload);
            long.push(0);
            agree(&frame(&long));
            for k in 0..payload.len() {
                let mut p = StdVec::from(payload);
                p[k] = p[k].wrapping_add(1);
                agree(&frame(&p));
                cases += 1;
            }
        }
        assert!(cases > 1000, "{cases}");
        // Decoding into a fresh placeholder works as well.
        let mut place = placeholder();
        assert_eq!(decode_into(&encode(&blobs[1]), &mut place), Ok(()));
        assert_eq!(place, blobs[1]);
        assert_eq!(place.validate(), Ok(()));
        assert_eq!(placeholder().validate(), Err(BlobError::TopologyMismatch));
    }
}
