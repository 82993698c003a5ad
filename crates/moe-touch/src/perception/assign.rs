//! Optimal assignment with a gate: markers to clusters, one to one, each marker either matched
//! within its gate or left unassigned.

/// Minimum-cost one-to-one assignment of rows to columns where a row may also stay unassigned.
///
/// `cost[r][c]` is the cost of giving column `c` to row `r` (`f64::INFINITY`: not allowed, e.g.
/// outside the gate); `unassigned[r]` is what leaving row `r` without a column costs. Returns,
/// per row, its column or `None`. No column goes to two rows.
///
/// Solved exactly as a square assignment problem (the Hungarian method with potentials,
/// O(n³)) on the matrix padded with one private "unassigned" column per row and one "unused"
/// row per column.
pub(super) fn assign_gated(cost: &[Vec<f64>], unassigned: &[f64]) -> Vec<Option<usize>> {
    let rows = cost.len();
    let cols = cost.first().map_or(0, Vec::len);
    if rows == 0 {
        return Vec::new();
    }
    let n = rows + cols;
    // A finite stand-in for "not allowed", larger than any feasible total.
    let finite_max = cost
        .iter()
        .flatten()
        .chain(unassigned)
        .filter(|c| c.is_finite())
        .fold(0.0f64, |m, &c| m.max(c.abs()));
    let forbidden = (finite_max + 1.0) * (n as f64 + 1.0) * 4.0;
    let entry = |r: usize, c: usize| -> f64 {
        match (r < rows, c < cols) {
            (true, true) => {
                let v = cost[r][c];
                if v.is_finite() { v } else { forbidden }
            }
            (true, false) => {
                if c - cols == r && unassigned[r].is_finite() {
                    unassigned[r]
                } else {
                    forbidden
                }
            }
            // Padding rows take any real column (that column stays unused) or any padding
            // column, for free.
            (false, _) => 0.0,
        }
    };
    let column_of_row = hungarian(n, entry);
    (0..rows)
        .map(|r| {
            let c = column_of_row[r];
            (c < cols && cost[r][c].is_finite()).then_some(c)
        })
        .collect()
}

/// Square assignment problem of size `n` with costs `entry(row, column)`: the column of every
/// row in a minimum-cost perfect matching (shortest augmenting paths with row and column
/// potentials).
fn hungarian(n: usize, entry: impl Fn(usize, usize) -> f64) -> Vec<usize> {
    // 1-based with a virtual column 0, as in the classic formulation.
    let mut u = vec![0.0; n + 1];
    let mut v = vec![0.0; n + 1];
    let mut row_of_col = vec![0usize; n + 1];
    let mut way = vec![0usize; n + 1];
    for r in 1..=n {
        row_of_col[0] = r;
        let mut c0 = 0usize;
        let mut minv = vec![f64::INFINITY; n + 1];
        let mut used = vec![false; n + 1];
        loop {
            used[c0] = true;
            let r0 = row_of_col[c0];
            let mut delta = f64::INFINITY;
            let mut c1 = 0usize;
            for c in 1..=n {
                if used[c] {
                    continue;
                }
                let cur = entry(r0 - 1, c - 1) - u[r0] - v[c];
                if cur < minv[c] {
                    minv[c] = cur;
                    way[c] = c0;
                }
                if minv[c] < delta {
                    delta = minv[c];
                    c1 = c;
                }
            }
            for c in 0..=n {
                if used[c] {
                    u[row_of_col[c]] += delta;
                    v[c] -= delta;
                } else {
                    minv[c] -= delta;
                }
            }
            c0 = c1;
            if row_of_col[c0] == 0 {
                break;
            }
        }
        loop {
            let c1 = way[c0];
            row_of_col[c0] = row_of_col[c1];
            c0 = c1;
            if c0 == 0 {
                break;
            }
        }
    }
    let mut col_of_row = vec![0usize; n];
    for c in 1..=n {
        col_of_row[row_of_col[c] - 1] = c - 1;
    }
    col_of_row
}

#[cfg(test)]
mod tests {
    use super::*;
    use moe_geom::SeededRng;

    /// The best total by trying every partial injective assignment.
    fn brute_force(cost: &[Vec<f64>], unassigned: &[f64]) -> f64 {
        fn go(r: usize, used: &mut Vec<bool>, cost: &[Vec<f64>], un: &[f64]) -> f64 {
            if r == cost.len() {
                return 0.0;
            }
            let mut best = un[r] + go(r + 1, used, cost, un);
            for c in 0..used.len() {
                if !used[c] && cost[r][c].is_finite() {
                    used[c] = true;
                    best = best.min(cost[r][c] + go(r + 1, used, cost, un));
                    used[c] = false;
                }
            }
            best
        }
        let cols = cost.first().map_or(0, Vec::len);
        go(0, &mut vec![false; cols], cost, unassigned)
    }

    fn total(cost: &[Vec<f64>], unassigned: &[f64], a: &[Option<usize>]) -> f64 {
        a.iter()
            .enumerate()
            .map(|(r, c)| c.map_or(unassigned[r], |c| cost[r][c]))
            .sum()
    }

    #[test]
    fn matches_brute_force_on_random_gated_problems() {
        let mut rng = SeededRng::new(11);
        for trial in 0..300 {
            let rows = 1 + (trial % 5);
            let cols = trial % 6;
            let cost: Vec<Vec<f64>> = (0..rows)
                .map(|_| {
                    (0..cols)
                        .map(|_| {
                            let c = rng.uniform_range(0.0, 10.0);
                            if c > 7.0 { f64::INFINITY } else { c }
                        })
                        .collect()
                })
                .collect();
            let unassigned: Vec<f64> = (0..rows).map(|_| rng.uniform_range(2.0, 8.0)).collect();
            let a = assign_gated(&cost, &unassigned);
            assert_eq!(a.len(), rows);
            let mut taken = vec![false; cols];
            for c in a.iter().flatten() {
                assert!(!taken[*c], "column {c} assigned twice");
                taken[*c] = true;
            }
            let best = brute_force(&cost, &unassigned);
            assert!(
                (total(&cost, &unassigned, &a) - best).abs() < 1e-9,
                "trial {trial}: {} vs {best}",
                total(&cost, &unassigned, &a)
            );
        }
    }

    #[test]
    fn a_contested_column_goes_where_it_costs_least_overall() {
        // Row 0 alone would take column 0 (1.0), but row 1 can only use column 0: the optimum
        // gives row 0 column 1.
        let inf = f64::INFINITY;
        let cost = vec![vec![1.0, 1.5], vec![1.2, inf]];
        assert_eq!(assign_gated(&cost, &[5.0, 5.0]), vec![Some(1), Some(0)]);
        // Nothing within the gate: unassigned.
        assert_eq!(assign_gated(&[vec![inf, inf]], &[1.0]), vec![None]);
        assert_eq!(assign_gated(&[vec![]], &[1.0]), vec![None]);
        assert!(assign_gated(&[], &[]).is_empty());
    }
}
