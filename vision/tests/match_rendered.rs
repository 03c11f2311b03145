//! The matcher on rendered chessboards (the repetitive worst case) with exact truth.
//!
//! Parameters were chosen with the development seeds of `dev_sweep` (1..=4, run with
//! `cargo test --release -p hvs-vision --test match_rendered -- --ignored --nocapture`);
//! the asserting tests use held-out seeds (1001, 1002) that played no part in the choice.

mod match_common;
use hvs_vision::matching::MatchParams;
use match_common::{eval_case, eval_case_with, Interval, Rates};

#[test]
#[ignore = "development sweep: prints rates for the development seeds"]
fn dev_sweep() {
    for seed in 1..=4u64 {
        for case in 1..=4u8 {
            let (c, r) = eval_case(case, seed, 50, MatchParams::default());
            eprintln!("seed {seed} case {case} corners: {}", c.summary());
            eprintln!("seed {seed} case {case} random:  {}", r.summary());
            let (c, r) =
                eval_case_with(case, seed, 50, MatchParams::default(), Interval::Fixed(10.0, 60.0));
            eprintln!("seed {seed} case {case} corners 10..60: {}", c.summary());
            eprintln!("seed {seed} case {case} random 10..60:  {}", r.summary());
        }
    }
}

#[test]
fn corners_of_rendered_boards_all_cases() {
    let mut all = Rates::default();
    for case in 1..=4u8 {
        for seed in [1001u64, 1002] {
            let (c, _) = eval_case(case, seed, 0, MatchParams::default());
            all.merge(&c);
        }
    }
    eprintln!("cases I-IV corners: {}", all.summary());
    assert!(all.returned() >= 0.40, "{}", all.summary());
    assert!(all.within(0.5) >= 0.99, "{}", all.summary());
}

#[test]
fn wide_interval_on_the_repetitive_board_refuses_rather_than_guesses() {
    // Without the model's narrow interval (all the training volume's disparities, 10..60 px,
    // against squares of 10-26 px) the board repeats inside the search: the matcher must
    // call those points ambiguous (or grow its window until it is unique), and what it does
    // return must still be right.
    let (mut corners, mut random) = (Rates::default(), Rates::default());
    for seed in [1001u64, 1002] {
        let (c, r) =
            eval_case_with(1, seed, 50, MatchParams::default(), Interval::Fixed(10.0, 60.0));
        corners.merge(&c);
        random.merge(&r);
    }
    eprintln!("case I, interval 10..60 px, corners: {}", corners.summary());
    eprintln!("case I, interval 10..60 px, random points: {}", random.summary());
    // Some points stay ambiguous even with the grown windows (those whose window can reach
    // no edge of the board): they are refused as such, not guessed.
    for r in [&corners, &random] {
        let amb = r.status.get("ambiguous").copied().unwrap_or(0);
        assert!(amb >= r.asked / 10, "{}", r.summary());
    }
    assert!(corners.within(0.5) >= 0.99, "{}", corners.summary());
    assert!(random.within(1.0) >= 0.95, "{}", random.summary());
    assert!(random.at_least(2.0) <= 0.02, "{}", random.summary());
}

#[test]
fn random_board_points_narrow_interval() {
    // Points anywhere on the squares (flat insides, edges, corners) with the model's interval.
    let mut all = Rates::default();
    for case in [1u8, 3] {
        let (_, r) = eval_case(case, 1003, 60, MatchParams::default());
        all.merge(&r);
    }
    eprintln!("cases I+III random board points: {}", all.summary());
    assert!(all.returned() >= 0.6, "{}", all.summary());
    assert!(all.within(1.0) >= 0.97, "{}", all.summary());
    assert!(all.at_least(2.0) <= 0.02, "{}", all.summary());
}
