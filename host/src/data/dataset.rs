//! The in-memory data set that every command passes around: inputs (pixels, and for
//! posture-aware sets the five joint angles) with optional ground-truth positions.

use hvs_shared::runtime::blob::InputKind;
use hvs_shared::runtime::gaze::Joints;

/// Names of the four pixel columns, in input order.
pub const PIXEL_COLUMNS: [&str; 4] = ["u_l", "v_l", "u_r", "v_r"];
/// Names of the five joint-angle columns (degrees) of posture-aware sets, in input order.
pub const JOINT_COLUMNS: [&str; 5] =
    ["neck_pan", "neck_tilt", "eye_tilt", "left_eye_pan", "right_eye_pan"];
/// Names of the ground-truth columns (cm).
pub const TARGET_COLUMNS: [&str; 3] = ["x", "y", "z"];

/// Rows of inputs, row-major, and their ground truth when known.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Dataset {
    /// Number of inputs per row (4, or 9 with joint angles).
    pub n_inputs: usize,
    /// `rows * n_inputs` values, row-major.
    pub inputs: Vec<f64>,
    /// Ground truth `[x, y, z]` per row (empty when the set has none).
    pub targets: Vec<[f64; 3]>,
}

impl Dataset {
    /// An empty set of the given input kind.
    pub fn new(kind: InputKind) -> Self {
        Dataset { n_inputs: kind.len(), inputs: Vec::new(), targets: Vec::new() }
    }
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.inputs.len().checked_div(self.n_inputs).unwrap_or(0)
    }
    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Inputs of row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.inputs[i * self.n_inputs..(i + 1) * self.n_inputs]
    }
    /// Row `i`'s five joint angles (degrees, as the `f32` the head reports them) when the set
    /// is posture-aware, `None` otherwise.
    pub fn joints(&self, i: usize) -> Option<Joints> {
        (self.input_kind() == Some(InputKind::StereoJoints)).then(|| {
            let r = self.row(i);
            Joints([r[4], r[5], r[6], r[7], r[8]].map(|v| v as f32))
        })
    }
    /// Whether every row has a ground truth.
    pub fn has_targets(&self) -> bool {
        !self.is_empty() && self.targets.len() == self.len()
    }
    /// The input kind implied by the number of inputs.
    pub fn input_kind(&self) -> Option<InputKind> {
        match self.n_inputs {
            4 => Some(InputKind::Stereo),
            9 => Some(InputKind::StereoJoints),
            _ => None,
        }
    }
    /// Appends one row.
    pub fn push(&mut self, inputs: &[f64], target: Option<[f64; 3]>) {
        debug_assert_eq!(inputs.len(), self.n_inputs);
        self.inputs.extend_from_slice(inputs);
        if let Some(t) = target {
            self.targets.push(t);
        }
    }
    /// FNV-1a 64 over the bit patterns of every input and target: the training-set hash
    /// stored in a blob.
    pub fn hash(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |v: f64| {
            for b in v.to_bits().to_le_bytes() {
                h ^= b as u64;
                h = h.wrapping_mul(0x0100_0000_01b3);
            }
        };
        for v in &self.inputs {
            eat(*v);
        }
        for t in &self.targets {
            t.iter().for_each(|v| eat(*v));
        }
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_and_hash() {
        let mut d = Dataset::new(InputKind::Stereo);
        assert!(d.is_empty());
        d.push(&[1.0, 2.0, 3.0, 4.0], Some([0.0, 0.0, 65.0]));
        d.push(&[5.0, 6.0, 7.0, 8.0], Some([1.0, 0.0, 65.0]));
        assert_eq!(d.len(), 2);
        assert_eq!(d.row(1), &[5.0, 6.0, 7.0, 8.0]);
        assert!(d.has_targets());
        let h = d.hash();
        d.targets[1][2] = 66.0;
        assert_ne!(h, d.hash());
    }
}
