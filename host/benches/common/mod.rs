//! What the training benches share.
// Each bench uses a different subset.
#![allow(dead_code)]

use hvs_host::data::dataset::Dataset;
use hvs_host::sim::board::TrainingBoard;
use hvs_host::sim::sets::{simulate, SetKind, SimOptions};
use hvs_shared::runtime::blob::InputKind;
use hvs_shared::sim::presets;

/// The thesis' case-IV board set: the board protocol's 72 points at the training depths,
/// projected and rounded to whole pixels.
pub fn board_set() -> Dataset {
    grid_board_set(TrainingBoard::Thesis)
}

/// `board` at the thesis' six training depths through case IV, rounded pixels, as
/// `hvs simulate --case 4 --set train --board NAME` writes it (9x6:6: 324 points).
pub fn grid_board_set(board: TrainingBoard) -> Dataset {
    let opt = SimOptions { board, ..SimOptions::default() };
    let mut d = Dataset::new(InputKind::Stereo);
    for s in simulate(&presets::CASE_4, SetKind::Train, &opt).expect("case IV sees the board") {
        d.push(&s.px, Some(s.xyz));
    }
    d
}

/// `hvs simulate --case 3 --set train --postures grid --seed 1` (23,328 rows), read back
/// through the CSV reader `hvs train` uses.
pub fn posture_grid_set() -> Dataset {
    use hvs_host::sim::posture::{postures, simulate, write_csv, PostureOptions, Sampling};
    use hvs_shared::sim::posture::HeadRig;
    let opt = PostureOptions { sampling: Sampling::Grid, ..PostureOptions::default() };
    let joints =
        postures(&opt, 1 ^ hvs_host::sim::posture::POSTURE_SEED_MIX).expect("grid postures");
    let head = HeadRig::new(presets::CASE_3);
    let samples =
        simulate(&head, SetKind::Train, &joints, &SimOptions::default()).expect("case III");
    let mut csv = Vec::new();
    write_csv(&mut csv, &samples, true).expect("in memory");
    let name = std::path::Path::new("posture_train.csv");
    let table = hvs_host::data::csv::read_set_from(
        name,
        csv.as_slice(),
        hvs_host::data::csv::Inputs::Auto,
        true,
    )
    .expect("the simulated set reads back");
    assert_eq!(table.data.len(), 23_328, "the grid set");
    table.data
}
