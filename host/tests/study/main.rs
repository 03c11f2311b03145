//! Tests of the studies' library modules (`hvs_host::study`) through their public API, one
//! module per study.

mod accuracy;
mod engine;
mod posture;
mod template;
mod thesis;

/// Every index of the grid `0..dims[0]` x `0..dims[1]` x ..., last index fastest.
pub fn grid<const N: usize>(dims: [u64; N]) -> impl Iterator<Item = [u64; N]> {
    let total: u64 = dims.iter().product();
    (0..total).map(move |mut k| {
        let mut i = [0; N];
        for d in (0..N).rev() {
            (i[d], k) = (k % dims[d], k / dims[d]);
        }
        i
    })
}

/// Whether no two of `seeds` are equal.
pub fn distinct(seeds: impl IntoIterator<Item = u64>) -> bool {
    let mut seen = std::collections::HashSet::new();
    seeds.into_iter().all(|s| seen.insert(s))
}

#[test]
fn the_grid_visits_every_index_once_in_order() {
    let all: Vec<[u64; 2]> = grid([2, 3]).collect();
    assert_eq!(all, [[0, 0], [0, 1], [0, 2], [1, 0], [1, 1], [1, 2]]);
    assert!(distinct([1, 2, 3]) && !distinct([1, 2, 1]));
}
