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
