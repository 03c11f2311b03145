//! What the training benches share.

use hvs_host::data::dataset::Dataset;
use hvs_shared::runtime::blob::InputKind;
use hvs_shared::sim::presets;

/// The thesis' case-IV board set: the board protocol's 72 points at the training depths,
/// projected and rounded to whole pixels.
pub fn board_set() -> Dataset {
    let rig = presets::CASE_4;
    let mut d = Dataset::new(InputKind::Stereo);
    for z in presets::TRAIN_DEPTHS {
        for p in presets::board_points(z) {
            d.push(&rig.project_rounded(&p).unwrap(), Some(p));
        }
    }
    d
}
