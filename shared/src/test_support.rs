//! Sample models for the tests of every crate (feature `test-support`): one constructor, so no
//! test writes a `ModelBlob { .. }` literal of its own.
//!
//! The weights are seeded (same spec, same bytes), not trained: enough for round trips,
//! bit-for-bit comparisons, slot rules and instruction counts. The scaling and the training
//! input box are those of case I's training set (pixels) and of the posture working range
//! (joints, degrees).

use crate::runtime::blob::{
    Algorithm, Family, InputKind, ModelBlob, OutputFrame, OutputKind, Topology, TrainingMeta,
    MAX_INPUTS, MAX_OUTPUTS, MAX_PARAMS,
};
use crate::runtime::mlp::{param_count, Activation, OutputMap};
use crate::runtime::traditional::Calibration;
use heapless::Vec;

/// One `const fn field(self, value) -> SampleSpec` per field: the builder methods of
/// [`SampleSpec`] (methods, which a function cannot declare).
macro_rules! spec_setters {
    ($($(#[$doc:meta])* $field:ident: $ty:ty,)*) => {
        $(
            $(#[$doc])*
            pub const fn $field(self, $field: $ty) -> SampleSpec {
                SampleSpec { $field, ..self }
            }
        )*
    };
}

/// What a sample model looks like.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleSpec {
    /// Inputs (4 pixels, or 4 pixels and 5 joints).
    pub inputs: InputKind,
    /// Hidden neurons.
    pub hidden: u8,
    /// Outputs.
    pub outputs: OutputKind,
    /// Blob generation.
    pub generation: u32,
    /// Seed of the weights (and `meta.seed`).
    pub seed: u64,
    /// Weights are drawn uniformly in `[-amplitude, amplitude)`.
    pub amplitude: f32,
    /// The traditional method's calibration carried as the fallback.
    pub fallback: Option<Calibration>,
    /// The model family (how the outputs map to cm).
    pub family: Family,
    /// The frame of the net's points (eye platform, cyclopean: posture-aware nets only).
    pub frame: OutputFrame,
}

impl SampleSpec {
    /// A 4-5-3 X, Y, Z net, generation 1, seed 0, weights in [-1, 1), no fallback.
    pub const THESIS: SampleSpec = SampleSpec {
        inputs: InputKind::Stereo,
        hidden: 5,
        outputs: OutputKind::Xyz,
        generation: 1,
        seed: 0,
        amplitude: 1.0,
        fallback: None,
        family: Family::THESIS,
        frame: OutputFrame::Head,
    };

    spec_setters! {
        /// This spec with `hidden` neurons.
        hidden: u8,
        /// This spec with these inputs.
        inputs: InputKind,
        /// This spec with these outputs.
        outputs: OutputKind,
        /// This spec at `generation`.
        generation: u32,
        /// This spec in `family`.
        family: Family,
        /// This spec with its points in `frame`.
        frame: OutputFrame,
        /// This spec with weights from `seed`.
        seed: u64,
    }
    /// The model.
    pub fn build(self) -> ModelBlob {
        sample(self)
    }
}

const PX_OFFSET: [f32; 4] = [343.0, 240.0, 297.0, 240.0];
const PX_SCALE: [f32; 4] = [1.0 / 30.0, 1.0 / 12.0, 1.0 / 30.0, 1.0 / 12.0];
const PX_MIN: [f32; 4] = [325.0, 228.0, 279.0, 228.0];
const PX_MAX: [f32; 4] = [361.0, 252.0, 315.0, 252.0];
const JOINT_SCALE: [f32; 5] = [1.0 / 30.0, 1.0 / 20.0, 1.0 / 15.0, 1.0 / 20.0, 1.0 / 20.0];
const JOINT_MIN: [f32; 5] = [-30.0, -20.0, -15.0, -20.0, -20.0];
const XYZ_OFFSET: [f32; 3] = [0.0, 0.0, 115.0];
const XYZ_SCALE: [f32; 3] = [3.0, 2.0, 50.0];
/// X/Z, Y/Z, 1/Z of the training volume (Z 65..165 cm): 1/Z stays positive.
const INV_OFFSET: [f32; 3] = [0.0, 0.0, 0.01];
const INV_SCALE: [f32; 3] = [0.02, 0.02, 0.002];

/// The sample model of `spec`.
pub fn sample(spec: SampleSpec) -> ModelBlob {
    let (ni, no) = (spec.inputs.len(), spec.outputs.len());
    let joints = ni > 4;
    let mut state = if joints {
        spec.seed ^ 0x9e37_79b9_7f4a_7c15
    } else {
        spec.seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407)
    };
    let mut params: Vec<f32, MAX_PARAMS> = Vec::new();
    for _ in 0..param_count(ni, spec.hidden as usize, no) + spec.family.skip_len(ni, no) {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let r = ((state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0;
        params.push(r * spec.amplitude).expect("a sample topology fits the blob");
    }
    let with_joints = |px: [f32; 4], j: [f32; 5]| -> Vec<f32, MAX_INPUTS> {
        let mut v = Vec::from_slice(&px).expect("4 <= MAX_INPUTS");
        if joints {
            v.extend_from_slice(&j).expect("9 <= MAX_INPUTS");
        }
        v
    };
    let out = |all: [f32; 3]| -> Vec<f32, MAX_OUTPUTS> {
        Vec::from_slice(&all[3 - no..]).expect("outputs <= 3")
    };
    ModelBlob {
        generation: spec.generation,
        topology: Topology {
            inputs: spec.inputs,
            hidden: spec.hidden,
            outputs: spec.outputs,
            output_activation: Activation::Linear,
        },
        in_offset: with_joints(PX_OFFSET, [0.0; 5]),
        in_scale: with_joints(PX_SCALE, JOINT_SCALE),
        out_offset: out(match spec.family.output_map {
            OutputMap::Direct => XYZ_OFFSET,
            OutputMap::InverseDepth => INV_OFFSET,
        }),
        out_scale: out(match spec.family.output_map {
            OutputMap::Direct => XYZ_SCALE,
            OutputMap::InverseDepth => INV_SCALE,
        }),
        params,
        in_min: with_joints(PX_MIN, JOINT_MIN),
        in_max: with_joints(PX_MAX, JOINT_MIN.map(|v| -v)),
        meta: TrainingMeta {
            seed: spec.seed,
            train_hash: 0x1234_5678_9abc_def0,
            train_points: 72,
            train_error_pct: 0.5,
            algorithm: Algorithm::Lm,
            restarts: 1,
        },
        fallback: spec.fallback,
        family: spec.family,
        matcher: None,
        frame: spec.frame,
        image_size: None,
        parent: None,
    }
}

/// A valid 4-5-3 blob with seeded weights in [-2, 2) and the built-in fallback: the model of the
/// fuzz seeds, the fault-injection tests and the firmware's instruction count.
pub fn sample_model(generation: u32, seed: u64) -> ModelBlob {
    sample(legacy(generation, seed))
}

/// The spec of [`sample_model`].
fn legacy(generation: u32, seed: u64) -> SampleSpec {
    SampleSpec {
        generation,
        seed,
        amplitude: 2.0,
        fallback: Some(Calibration::BUILT_IN),
        ..SampleSpec::THESIS
    }
}

/// [`sample_model`] in the default family of `hvs train` (inverse depth with a linear skip
/// term): the firmware's instruction count of the default.
pub fn sample_default_model(generation: u32, seed: u64) -> ModelBlob {
    sample(SampleSpec { family: Family::INVERSE_DEPTH_SKIP, ..legacy(generation, seed) })
}

/// A valid posture-aware 9-8-3 blob (four pixels, five joint angles in degrees), built like
/// [`sample_model`]: the larger blob of the fault-injection tests.
pub fn sample_posture_model(generation: u32, seed: u64) -> ModelBlob {
    sample_posture_model_hidden(generation, seed, 8)
}

/// [`sample_posture_model`] with `hidden` hidden units, e.g. the 9-16-3 net of
/// `firmware/measure.sh`'s stack workload.
pub fn sample_posture_model_hidden(generation: u32, seed: u64, hidden: u8) -> ModelBlob {
    sample(SampleSpec {
        inputs: InputKind::StereoJoints,
        hidden,
        ..SampleSpec {
            generation,
            seed,
            amplitude: 2.0,
            fallback: Some(Calibration::BUILT_IN),
            ..SampleSpec::THESIS
        }
    })
}

/// [`sample_posture_model_hidden`] in the default family of `hvs train` (inverse depth with a
/// linear skip term over the nine inputs) with its points in the cyclopean frame: the
/// posture-aware net `hvs train` writes, for `firmware/measure.sh`'s stack workload and
/// instruction count.
pub fn sample_default_posture_model(generation: u32, seed: u64, hidden: u8) -> ModelBlob {
    sample(SampleSpec {
        inputs: InputKind::StereoJoints,
        hidden,
        family: Family::INVERSE_DEPTH_SKIP,
        frame: OutputFrame::Cyclopean,
        ..legacy(generation, seed)
    })
}

/// One SplitMix64 step (Steele, Lea, Flood 2014): advances `state`, returns the next 64
/// random bits. The seeded generator of tests, examples and fuzzers (same seed, same bits).
pub fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_valid_and_seeded() {
        for spec in [
            SampleSpec::THESIS,
            SampleSpec::THESIS.hidden(10).outputs(OutputKind::Z),
            SampleSpec::THESIS.inputs(InputKind::StereoJoints).hidden(16),
        ] {
            let b = sample(spec);
            assert_eq!(b.n_inputs(), spec.inputs.len());
            let mut buf = [0u8; crate::runtime::blob::MAX_BLOB_LEN];
            let n = b.encode(&mut buf).unwrap();
            assert_eq!(crate::runtime::blob::decode(&buf[..n]).unwrap(), b);
            assert_eq!(sample(spec), b);
            assert_ne!(sample(spec.seed(1)).params, b.params);
        }
    }
}
