//! The fast form (two per-point products and a fused reduction) against the network written
//! out per edge, and the invariances of a point-set network.

use moe_contact::candle_core::DType;
use moe_contact::{Aggregation, Mode, ModelWeights};

use crate::common::{
    literal_forward, max_abs_diff, random_points, seeded_net, small_config, tensor, values,
};

#[test]
fn the_fast_form_equals_the_literal_per_edge_network() {
    let (sets, n, c) = (2, 150, 3);
    for aggregation in [Aggregation::Max, Aggregation::Sum] {
        let config = small_config(aggregation);
        let weights = ModelWeights::seeded(&config, c, 11).unwrap();
        let net = seeded_net(&config, c, 11, DType::F64);
        let x = random_points(sets, n, c, 5);
        let out = net
            .forward_with(&tensor(&x, sets, n, c), Mode::Eval)
            .unwrap();
        let got = values(&out.logits);
        for s in 0..sets {
            let (want, tables) =
                literal_forward(&weights, &config, &x[s * n * c..(s + 1) * n * c], n, c);
            let got_s = &got[s * n * 2..(s + 1) * n * 2];
            let diff = max_abs_diff(got_s, &want);
            assert!(diff < 1e-12, "{aggregation}, set {s}: {diff:e}");
            // The neighbour tables are the definition's, nearest first.
            for (layer, table) in tables.iter().enumerate() {
                for (i, row) in table.iter().enumerate() {
                    let start = (s * n + i) * config.k;
                    let ours: Vec<usize> = out.neighbours[layer][start..start + config.k]
                        .iter()
                        .map(|&j| j as usize)
                        .collect();
                    assert_eq!(
                        &ours, row,
                        "{aggregation}, set {s}, layer {layer}, point {i}"
                    );
                }
            }
        }
    }
}

#[test]
fn permuting_the_points_permutes_the_outputs() {
    let (n, c) = (120, 3);
    for aggregation in [Aggregation::Max, Aggregation::Sum] {
        let config = small_config(aggregation);
        let net = seeded_net(&config, c, 3, DType::F64);
        let x = random_points(1, n, c, 9);
        // A fixed derangement: i -> (7i + 3) mod n (7 and 120 are coprime).
        let perm: Vec<usize> = (0..n).map(|i| (7 * i + 3) % n).collect();
        let xp: Vec<f64> = perm
            .iter()
            .flat_map(|&p| x[p * c..(p + 1) * c].to_vec())
            .collect();
        let a = values(
            &net.forward_with(&tensor(&x, 1, n, c), Mode::Eval)
                .unwrap()
                .logits,
        );
        let b = values(
            &net.forward_with(&tensor(&xp, 1, n, c), Mode::Eval)
                .unwrap()
                .logits,
        );
        for (i, &p) in perm.iter().enumerate() {
            for o in 0..2 {
                let (u, v) = (b[2 * i + o], a[2 * p + o]);
                assert!(
                    (u - v).abs() <= 1e-12 * (1.0 + v.abs()),
                    "{aggregation}: {u} vs {v}"
                );
            }
        }
    }
}

#[test]
fn sets_of_a_batch_do_not_see_each_other() {
    let (n, c) = (100, 3);
    let config = small_config(Aggregation::Max);
    let net = seeded_net(&config, c, 4, DType::F64);
    let x = random_points(3, n, c, 21);
    let batch = values(
        &net.forward_with(&tensor(&x, 3, n, c), Mode::Eval)
            .unwrap()
            .logits,
    );
    for s in 0..3 {
        let one = &x[s * n * c..(s + 1) * n * c];
        let alone = values(
            &net.forward_with(&tensor(one, 1, n, c), Mode::Eval)
                .unwrap()
                .logits,
        );
        let diff = max_abs_diff(&batch[s * n * 2..(s + 1) * n * 2], &alone);
        assert!(diff < 1e-12, "set {s}: {diff:e}");
    }
}
