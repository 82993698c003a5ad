//! Tests of the kernels against their definitions: the kNN selection, the neighbour minimum
//! and the dropout draws.

use super::*;

/// The k nearest by a full stable sort of (distance, index): the definition.
fn knn_by_sort(points: &[[f64; 2]], k: usize) -> Vec<Vec<u32>> {
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let mut d: Vec<(f64, u32)> = points
                .iter()
                .enumerate()
                .map(|(j, q)| {
                    let d = if i == j {
                        0.0
                    } else {
                        (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)
                    };
                    (d, j as u32)
                })
                .collect();
            d.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            d[..k].iter().map(|x| x.1).collect()
        })
        .collect()
}

#[test]
fn selection_equals_a_full_sort_with_ties_to_the_lower_index() {
    // Integer grid points: many exactly equal distances, and a duplicated point.
    let mut points: Vec<[f64; 2]> = (0..7)
        .flat_map(|x| (0..6).map(move |y| [f64::from(x), f64::from(y)]))
        .collect();
    points.push([3.0, 2.0]);
    let n = points.len();
    let flat: Vec<f64> = points.iter().flatten().copied().collect();
    for k in [1, 5, 9, n] {
        let got = knn_select(&flat, n, 2, k);
        let want = knn_by_sort(&points, k);
        for (i, w) in want.iter().enumerate() {
            assert_eq!(&got[i * k..(i + 1) * k], &w[..], "k = {k}, point {i}");
        }
    }
}

/// The minimum over the neighbours per channel and the first neighbour (in table order)
/// that attains it, one channel at a time: the definition.
fn min_by_definition(ab: &[f64], nbrs: &[u32], c: usize) -> (Vec<f64>, Vec<u32>) {
    (0..c)
        .map(|ch| {
            let b = |j: u32| ab[j as usize * 2 * c + c + ch];
            let mut best = (b(nbrs[0]), nbrs[0]);
            for &j in &nbrs[1..] {
                if b(j) < best.0 {
                    best = (b(j), j);
                }
            }
            best
        })
        .unzip()
}

#[test]
fn the_blocked_neighbour_minimum_is_the_first_neighbour_attaining_it() {
    let mut rng = moe_geom::SeededRng::new(5);
    // Channel counts below, at and across the register block; values on a coarse grid so
    // that exact ties between neighbours are common.
    for c in [3, MIN_BLOCK, 2 * MIN_BLOCK + 5] {
        let rows = 40;
        let ab: Vec<f64> = (0..rows * 2 * c)
            .map(|_| (rng.uniform() * 4.0).floor())
            .collect();
        let ab32: Vec<f32> = ab.iter().map(|&v| v as f32).collect();
        for trial in 0..50 {
            let k = 1 + trial % 12;
            let nbrs: Vec<u32> = (0..k).map(|_| rng.below(rows as u64) as u32).collect();
            let (want_min, want_arg) = min_by_definition(&ab, &nbrs, c);
            let mut acc = vec![0.0; c];
            let mut slot = vec![0.0; c];
            neighbour_min(&ab, &nbrs, c, &mut acc, Some(&mut slot));
            let arg: Vec<u32> = slot.iter().map(|s| nbrs[s.to_slot()]).collect();
            assert_eq!(acc, want_min, "c = {c}, k = {k}");
            assert_eq!(arg, want_arg, "c = {c}, k = {k}");
            let mut plain = vec![0.0; c];
            neighbour_min(&ab, &nbrs, c, &mut plain, None);
            assert_eq!(plain, want_min);
            let mut acc32 = vec![0.0f32; c];
            let mut slot32 = vec![0.0f32; c];
            neighbour_min(&ab32, &nbrs, c, &mut acc32, Some(&mut slot32));
            let arg32: Vec<u32> = slot32.iter().map(|s| nbrs[s.to_slot()]).collect();
            assert_eq!(arg32, want_arg, "f32, c = {c}, k = {k}");
        }
    }
}

#[test]
fn dropout_drops_exactly_the_draws_below_p() {
    // The integer comparison against ⌈p·2⁵³⌉ decides as `uniform() < p` does, for p that
    // are and are not multiples of 2⁻⁵³, across chunk boundaries.
    let count = 2 * DROPOUT_CHUNK + 3;
    let ones = vec![1.0f64; count];
    for p in [0.5, 0.3, 0.1, 1.0 / 3.0, 0.0, 0.999] {
        let op = Dropout {
            start: SeededRng::new(77),
            p,
            scale: 1.25,
        };
        let got = op.apply(&ones);
        let mut seq = SeededRng::new(77);
        for (e, &g) in got.iter().enumerate() {
            let want = if seq.uniform() < p { 0.0 } else { 1.25 };
            assert_eq!(g, want, "p = {p}, element {e}");
        }
    }
}
