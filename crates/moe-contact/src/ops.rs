//! CPU kernels of the DGCNN as candle custom ops: the partial-selection kNN and the fused
//! EdgeConv reductions with their backward passes.
//!
//! An EdgeConv layer's edge value is `ReLU(Θ(h_i − h_j) + Φh_i + b) = ReLU(A_i − B_j)` with
//! `A = h(Θ + Φ)ᵀ + b` and `B = hΘᵀ`, two per-point products. The reductions here take the
//! products side by side as one `(rows, 2C)` tensor `[A − b | B]` plus the bias, and never form
//! the `(rows, k, C)` edge tensor:
//! - max: `max_j ReLU(A_i − B_j) = ReLU(A_i − min_j B_j)` (ReLU and rounded subtraction are both
//!   monotone, so the two sides are equal in floating point), a gather-min per point;
//! - sum: `Σ_j ReLU(A_i − B_j)`, the paper's equation as written.
//!
//! Rows are the points of all point sets of a batch, set after set; neighbour indices are global
//! row numbers, so a set's neighbours stay within the set. Backward passes scatter into the
//! neighbours' rows, one point set per task, so results do not depend on the thread count.

use std::ops::{Add, AddAssign, Mul, Sub, SubAssign};
use std::sync::{Arc, OnceLock};

use candle_core::backend::BackendStorage;
use candle_core::{CpuStorage, CustomOp1, CustomOp2, CustomOp3, Layout, Shape, Tensor};
use faer::linalg::matmul::matmul;
use faer::{Accum, MatMut, MatRef, Par};
use rayon::prelude::*;

use moe_geom::SeededRng;

use crate::config::Aggregation;

/// The float types the kernels run in.
pub(crate) trait Elem:
    Copy
    + Send
    + Sync
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + AddAssign
    + SubAssign
    + faer::traits::ComplexField
    + 'static
{
    const ZERO: Self;
    const ONE: Self;
    const TWO: Self;
    fn min(self, other: Self) -> Self;
    /// `max(d, 0)`, with NaN as 0.
    fn positive_part(d: Self) -> Self;
    /// A small index (a neighbour's slot, below 2²⁴) as a value, exactly.
    fn from_slot(slot: usize) -> Self;
    /// The slot stored by [`Elem::from_slot`].
    fn to_slot(self) -> usize;
    /// An `f32` in this type (exact).
    fn from_f32(v: f32) -> Self;
    fn slice<'a>(s: &'a CpuStorage, l: &Layout, what: &str) -> candle_core::Result<&'a [Self]>;
    fn storage(v: Vec<Self>) -> CpuStorage;
}

macro_rules! elem {
    ($t:ty, $variant:ident) => {
        impl Elem for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const TWO: Self = 2.0;
            #[inline(always)]
            fn min(self, other: Self) -> Self {
                if other < self { other } else { self }
            }
            #[inline(always)]
            fn positive_part(d: Self) -> Self {
                if d > 0.0 { d } else { 0.0 }
            }
            #[inline(always)]
            fn from_slot(slot: usize) -> Self {
                slot as $t
            }
            #[inline(always)]
            fn to_slot(self) -> usize {
                self as usize
            }
            #[inline(always)]
            fn from_f32(v: f32) -> Self {
                v.into()
            }
            fn slice<'a>(
                s: &'a CpuStorage,
                l: &Layout,
                what: &str,
            ) -> candle_core::Result<&'a [Self]> {
                let CpuStorage::$variant(v) = s else {
                    candle_core::bail!("{what}: expected {}", stringify!($t))
                };
                let Some((start, end)) = l.contiguous_offsets() else {
                    candle_core::bail!("{what}: input must be contiguous")
                };
                Ok(&v[start..end])
            }
            fn storage(v: Vec<Self>) -> CpuStorage {
                CpuStorage::$variant(v)
            }
        }
    };
}
elem!(f32, F32);
elem!(f64, F64);

/// Runs `$body` with `$T` bound to the storage's float type.
macro_rules! dispatch {
    ($storage:expr, $T:ident => $body:expr) => {
        match $storage {
            CpuStorage::F32(_) => {
                type $T = f32;
                $body
            }
            CpuStorage::F64(_) => {
                type $T = f64;
                $body
            }
            other => candle_core::bail!("unsupported dtype {:?}", other.dtype()),
        }
    };
}

// ---------------------------------------------------------------------------------------------
// kNN

/// Selects, for each point `i` of a set of features `(N, C)`, the `k` points `j` with the
/// smallest squared distance (exactly 0 for `j = i`), ties broken by the lower index, nearest
/// first; output `(N, k)` u32. Distances are `|h_i|² + |h_j|² − 2⟨h_i, h_j⟩` (clamped at 0),
/// the inner products a block of rows at a time (never the whole `N × N` matrix). Each row's `k`
/// nearest are selected among the points within a bound, not sorted whole.
pub(crate) struct KnnSelect {
    pub(crate) k: usize,
}

/// Rows selected one after another by one task: each row starts from the previous row's
/// neighbours, which are mostly near the new row too, so the bound is tight from the start and
/// the scan of the row is a vectorised comparison that rarely finds a candidate. Starting empty
/// would make a row whose candidates arrive in decreasing distance (mesh vertices stored ring by
/// ring) insert nearly all of them.
const ROWS_PER_TASK: usize = 64;
/// Candidates compared at once in the scan.
const LANES: usize = 16;

fn knn_select<T: Elem>(h: &[T], n: usize, c: usize, k: usize) -> Vec<u32> {
    let norms: Vec<T> = h
        .chunks_exact(c)
        .map(|r| r.iter().fold(T::ZERO, |s, &x| s + x * x))
        .collect();
    let all = MatRef::from_row_major_slice(h, n, c);
    let mut out = vec![0u32; n * k];
    out.par_chunks_mut(k * ROWS_PER_TASK)
        .enumerate()
        .for_each_init(Vec::new, |inner, (task, block)| {
            // This task's rows of the inner-product matrix, one block in cache (never N × N);
            // the buffer is reused by the tasks a worker runs (the product overwrites it).
            let first = task * ROWS_PER_TASK;
            let rows = block.len() / k;
            inner.resize(rows * n, T::ZERO);
            matmul(
                MatMut::from_row_major_slice_mut(&mut inner[..rows * n], rows, n),
                Accum::Replace,
                MatRef::from_row_major_slice(&h[first * c..(first + rows) * c], rows, c),
                all.transpose(),
                T::ONE,
                Par::Seq,
            );
            let mut prime: Vec<u32> = Vec::with_capacity(k);
            let mut candidates: Vec<(T, u32)> = Vec::with_capacity(4 * k);
            for (r, out_row) in block.chunks_mut(k).enumerate() {
                let i = first + r;
                let ni = norms[i];
                // Squared distances in place of the inner products, clamped at 0 (a select, so
                // the loop vectorises; a NaN from overflowing features becomes 0).
                let dist = &mut inner[r * n..(r + 1) * n];
                for (d, &nj) in dist.iter_mut().zip(&norms) {
                    *d = T::positive_part((ni + nj) - T::TWO * *d);
                }
                dist[i] = T::ZERO;
                let dist = &*dist;
                if r == 0 {
                    // The first row of a task starts from the indices around it.
                    let lo = i.saturating_sub(k / 2).min(n - k);
                    prime.clear();
                    prime.extend((lo..lo + k).map(|j| j as u32));
                }
                // Any k points bound the k-th smallest distance from above: the k nearest are
                // among the points within the largest distance of the primed ones.
                let bound = prime.iter().fold(T::ZERO, |m, &j| {
                    if dist[j as usize] > m {
                        dist[j as usize]
                    } else {
                        m
                    }
                });
                candidates.clear();
                for (c, chunk) in dist.chunks(LANES).enumerate() {
                    let lowest = chunk.iter().fold(chunk[0], |m, &d| m.min(d));
                    if lowest > bound {
                        continue;
                    }
                    for (l, &d) in chunk.iter().enumerate() {
                        if d <= bound {
                            candidates.push((d, (c * LANES + l) as u32));
                        }
                    }
                }
                // Distances are never NaN here (clamped above), so the order is total.
                let by_order = |a: &(T, u32), b: &(T, u32)| {
                    a.0.partial_cmp(&b.0)
                        .unwrap_or(std::cmp::Ordering::Equal)
                        .then(a.1.cmp(&b.1))
                };
                if candidates.len() > k {
                    candidates.select_nth_unstable_by(k - 1, by_order);
                    candidates.truncate(k);
                }
                candidates.sort_unstable_by(by_order);
                prime.clear();
                for (o, &(_, j)) in out_row.iter_mut().zip(candidates.iter()) {
                    *o = j;
                    prime.push(j);
                }
            }
        });
    out
}

impl CustomOp1 for KnnSelect {
    fn name(&self) -> &'static str {
        "knn-select"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> candle_core::Result<(CpuStorage, Shape)> {
        let (n, c) = l.shape().dims2()?;
        if self.k == 0 || self.k > n || c == 0 {
            candle_core::bail!("knn-select: k = {} for {n} points of {c} channels", self.k);
        }
        let idx = dispatch!(s, T => {
            knn_select::<T>(T::slice(s, l, "features")?, n, c, self.k)
        });
        Ok((CpuStorage::U32(idx), Shape::from((n, self.k))))
    }
}

// ---------------------------------------------------------------------------------------------
// EdgeConv reductions

/// The shared geometry of an EdgeConv reduction: `rows` points in sets of `set_len`, `c` output
/// channels, `k` neighbours per point as global row numbers.
#[derive(Debug, Clone)]
pub(crate) struct EdgeGraph {
    pub(crate) idx: Arc<Vec<u32>>,
    pub(crate) k: usize,
    pub(crate) set_len: usize,
}

impl EdgeGraph {
    fn check(&self, l_ab: &Layout, l_bias: &Layout) -> candle_core::Result<(usize, usize)> {
        let (rows, two_c) = l_ab.shape().dims2()?;
        let c = two_c / 2;
        if two_c % 2 != 0 || l_bias.shape().dims1()? != c {
            candle_core::bail!("edgeconv: products must be (rows, 2C) and the bias (C)");
        }
        if self.idx.len() != rows * self.k || self.set_len == 0 || rows % self.set_len != 0 {
            candle_core::bail!("edgeconv: neighbour table does not fit the products");
        }
        Ok((rows, c))
    }
}

/// The EdgeConv reduction, `(rows, 2C)` products and `(C)` bias → `(rows, C)`: for max
/// `out_i = ReLU(A_i + b − min_{j ∈ N(i)} B_j)`, for sum `out_i = Σ_{j ∈ N(i)} ReLU(A_i + b − B_j)`,
/// per channel.
pub(crate) struct EdgeReduce {
    graph: EdgeGraph,
    aggregation: Aggregation,
    keep_argmin: bool,
    /// With max aggregation and `keep_argmin`, the forward pass's per row and channel slot (in
    /// the row's neighbour list) of the neighbour attaining the minimum, for the backward pass.
    argmin: OnceLock<Arc<Vec<u8>>>,
}

impl EdgeReduce {
    /// The reduction over `graph`. With `keep_argmin` (a forward pass whose backward will run)
    /// and max aggregation, the forward pass also records which neighbour attains each minimum,
    /// and the backward pass reads it instead of searching the neighbours again.
    pub(crate) fn new(graph: EdgeGraph, aggregation: Aggregation, keep_argmin: bool) -> Self {
        Self {
            graph,
            aggregation,
            keep_argmin,
            argmin: OnceLock::new(),
        }
    }

    fn is_sum(&self) -> bool {
        self.aggregation == Aggregation::Sum
    }
}

/// Gradient of [`EdgeReduce`] with respect to the products: `(rows, 2C)`.
struct EdgeBackward {
    graph: EdgeGraph,
    sum: bool,
    /// The forward pass's minimising slots, if it kept them (max aggregation).
    argmin: Option<Arc<Vec<u8>>>,
}

/// Channels a register block of [`neighbour_min`] holds.
const MIN_BLOCK: usize = 8;

/// Minimum of `B` over row `i`'s neighbours, per channel, into `acc`; `arg` gets the slot in
/// `nbrs` (as a value, [`Elem::from_slot`]) of the first neighbour in table order that attains
/// it.
///
/// The channels go in blocks of [`MIN_BLOCK`] held in local arrays across all neighbours, so
/// the comparisons and selects stay in registers and vectorise (with the running minimum in
/// memory, the compiler turned the selects into one conditional store per channel).
#[inline]
fn neighbour_min<T: Elem>(ab: &[T], nbrs: &[u32], c: usize, acc: &mut [T], arg: Option<&mut [T]>) {
    let row = |j: u32| &ab[j as usize * 2 * c + c..j as usize * 2 * c + 2 * c];
    let first = row(nbrs[0]);
    match arg {
        None => {
            acc.copy_from_slice(first);
            for &j in &nbrs[1..] {
                for (a, &v) in acc.iter_mut().zip(row(j)) {
                    *a = a.min(v);
                }
            }
        }
        Some(arg) => {
            let full = c - c % MIN_BLOCK;
            for lo in (0..full).step_by(MIN_BLOCK) {
                let mut m = [T::ZERO; MIN_BLOCK];
                let mut g = [T::ZERO; MIN_BLOCK];
                m.copy_from_slice(&first[lo..lo + MIN_BLOCK]);
                for (slot, &j) in nbrs.iter().enumerate().skip(1) {
                    let s = T::from_slot(slot);
                    let b = &row(j)[lo..lo + MIN_BLOCK];
                    for l in 0..MIN_BLOCK {
                        let lower = b[l] < m[l];
                        m[l] = if lower { b[l] } else { m[l] };
                        g[l] = if lower { s } else { g[l] };
                    }
                }
                acc[lo..lo + MIN_BLOCK].copy_from_slice(&m);
                arg[lo..lo + MIN_BLOCK].copy_from_slice(&g);
            }
            for ch in full..c {
                let mut m = first[ch];
                let mut g = T::ZERO;
                for (slot, &j) in nbrs.iter().enumerate().skip(1) {
                    let b = row(j)[ch];
                    if b < m {
                        m = b;
                        g = T::from_slot(slot);
                    }
                }
                acc[ch] = m;
                arg[ch] = g;
            }
        }
    }
}

/// The forward reduction; with `argmin` (max aggregation only), also the slot of the
/// minimising neighbour per row and channel, `(rows, C)`.
fn edge_forward<T: Elem>(
    ab: &[T],
    bias: &[T],
    g: &EdgeGraph,
    rows: usize,
    c: usize,
    sum: bool,
    argmin: bool,
) -> (Vec<T>, Option<Vec<u8>>) {
    let k = g.k;
    let mut out = vec![T::ZERO; rows * c];
    // Row i of the max reduction, `ReLU(A_i + b − min_j B_j)`, the minimising slots into `arg`.
    let max_row = |i: usize, out: &mut [T], acc: &mut [T], arg: Option<&mut [T]>| {
        neighbour_min(ab, &g.idx[i * k..(i + 1) * k], c, acc, arg);
        let a = &ab[i * 2 * c..i * 2 * c + c];
        for (((o, &a), &bias), &m) in out.iter_mut().zip(a).zip(bias).zip(acc.iter()) {
            let e = (a + bias) - m;
            *o = if e > T::ZERO { e } else { T::ZERO };
        }
    };
    if argmin && !sum {
        let mut slots = vec![0u8; rows * c];
        out.par_chunks_mut(c)
            .zip(slots.par_chunks_mut(c))
            .enumerate()
            .for_each_init(
                || (vec![T::ZERO; c], vec![T::ZERO; c]),
                |(acc, arg), (i, (out, slots))| {
                    max_row(i, out, acc, Some(arg));
                    // Slots are below k ≤ MAX_K = 256.
                    for (s, &v) in slots.iter_mut().zip(arg.iter()) {
                        *s = v.to_slot() as u8;
                    }
                },
            );
        return (out, Some(slots));
    }
    out.par_chunks_mut(c).enumerate().for_each_init(
        || vec![T::ZERO; c],
        |acc, (i, out)| {
            if sum {
                let a = &ab[i * 2 * c..i * 2 * c + c];
                for &j in &g.idx[i * k..(i + 1) * k] {
                    let b = &ab[j as usize * 2 * c + c..j as usize * 2 * c + 2 * c];
                    for (((o, &a), &bias), &b) in out.iter_mut().zip(a).zip(bias).zip(b) {
                        let e = (a + bias) - b;
                        if e > T::ZERO {
                            *o += e;
                        }
                    }
                }
            } else {
                max_row(i, out, acc, None);
            }
        },
    );
    (out, None)
}

/// The reduction a backward pass differentiates.
#[derive(Clone, Copy)]
enum Reduction<'a> {
    Sum,
    /// With the forward pass's minimising slots, `(rows, C)`, if it kept them.
    Max {
        argmin: Option<&'a [u8]>,
    },
}

fn edge_backward<T: Elem>(
    ab: &[T],
    bias: &[T],
    grad: &[T],
    g: &EdgeGraph,
    rows: usize,
    c: usize,
    reduction: Reduction<'_>,
) -> Vec<T> {
    let k = g.k;
    let set = g.set_len;
    let mut d_ab = vec![T::ZERO; rows * 2 * c];
    // One point set per task: the scatter into B's rows stays within the set.
    d_ab.par_chunks_mut(set * 2 * c)
        .enumerate()
        .for_each(|(s, d_set)| {
            let base = s * set;
            let mut acc = vec![T::ZERO; c];
            let mut arg = vec![T::ZERO; c];
            for li in 0..set {
                let i = base + li;
                let nbrs = &g.idx[i * k..(i + 1) * k];
                let a = &ab[i * 2 * c..i * 2 * c + c];
                let gi = &grad[i * c..(i + 1) * c];
                if let Reduction::Sum = reduction {
                    for &j in nbrs {
                        let lj = j as usize - base;
                        let b = &ab[j as usize * 2 * c + c..j as usize * 2 * c + 2 * c];
                        for ch in 0..c {
                            if (a[ch] + bias[ch]) - b[ch] > T::ZERO {
                                d_set[li * 2 * c + ch] += gi[ch];
                                d_set[lj * 2 * c + c + ch] -= gi[ch];
                            }
                        }
                    }
                } else if let Reduction::Max {
                    argmin: Some(saved),
                } = reduction
                {
                    // The forward pass's slots: the minimum is the slot's value, exactly.
                    let slots = &saved[i * c..(i + 1) * c];
                    for ch in 0..c {
                        let j = nbrs[usize::from(slots[ch])] as usize;
                        let m = ab[j * 2 * c + c + ch];
                        if (a[ch] + bias[ch]) - m > T::ZERO {
                            d_set[li * 2 * c + ch] += gi[ch];
                            d_set[(j - base) * 2 * c + c + ch] -= gi[ch];
                        }
                    }
                } else {
                    neighbour_min(ab, nbrs, c, &mut acc, Some(&mut arg));
                    for ch in 0..c {
                        if (a[ch] + bias[ch]) - acc[ch] > T::ZERO {
                            d_set[li * 2 * c + ch] += gi[ch];
                            let lj = nbrs[arg[ch].to_slot()] as usize - base;
                            d_set[lj * 2 * c + c + ch] -= gi[ch];
                        }
                    }
                }
            }
        });
    d_ab
}

fn edge_bwd(
    g: &EdgeGraph,
    sum: bool,
    argmin: Option<Arc<Vec<u8>>>,
    ab: &Tensor,
    bias: &Tensor,
    grad: &Tensor,
) -> candle_core::Result<(Option<Tensor>, Option<Tensor>)> {
    let c = bias.dim(0)?;
    let d_ab = ab.apply_op3_no_bwd(
        bias,
        &grad.contiguous()?,
        &EdgeBackward {
            graph: g.clone(),
            sum,
            argmin,
        },
    )?;
    // The bias enters beside A, so its gradient is A's summed over the rows.
    let d_bias = d_ab.narrow(1, 0, c)?.sum(0)?;
    Ok((Some(d_ab), Some(d_bias)))
}

impl CustomOp2 for EdgeReduce {
    fn name(&self) -> &'static str {
        match self.aggregation {
            Aggregation::Max => "edgeconv-max",
            Aggregation::Sum => "edgeconv-sum",
        }
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let g = &self.graph;
        let (rows, c) = g.check(l1, l2)?;
        let sum = self.is_sum();
        let keep = self.keep_argmin && !sum;
        if keep && g.k > usize::from(u8::MAX) + 1 {
            candle_core::bail!("edgeconv: k = {} neighbours have no one-byte slots", g.k);
        }
        let out = dispatch!(s1, T => {
            let ab = T::slice(s1, l1, "edge products")?;
            let bias = T::slice(s2, l2, "edge bias")?;
            let (out, argmin) = edge_forward::<T>(ab, bias, g, rows, c, sum, keep);
            if let Some(argmin) = argmin {
                // candle runs an op's forward once; a second run could not keep its slots.
                if self.argmin.set(Arc::new(argmin)).is_err() {
                    candle_core::bail!("edgeconv: forward run twice through one op");
                }
            }
            T::storage(out)
        });
        Ok((out, Shape::from((rows, c))))
    }

    fn bwd(
        &self,
        ab: &Tensor,
        bias: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> candle_core::Result<(Option<Tensor>, Option<Tensor>)> {
        let argmin = self.argmin.get().cloned();
        edge_bwd(&self.graph, self.is_sum(), argmin, ab, bias, grad)
    }
}

impl CustomOp3 for EdgeBackward {
    fn name(&self) -> &'static str {
        "edgeconv-backward"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (rows, c) = self.graph.check(l1, l2)?;
        if l3.shape().dims2()? != (rows, c) {
            candle_core::bail!("edgeconv-backward: gradient must be (rows, C)");
        }
        let out = dispatch!(s1, T => {
            let ab = T::slice(s1, l1, "edge products")?;
            let bias = T::slice(s2, l2, "edge bias")?;
            let grad = T::slice(s3, l3, "edge gradient")?;
            let reduction = match (self.sum, &self.argmin) {
                (true, _) => Reduction::Sum,
                (false, Some(a)) if a.len() == rows * c => Reduction::Max {
                    argmin: Some(a.as_slice()),
                },
                (false, Some(_)) => {
                    candle_core::bail!("edgeconv-backward: saved slots do not fit")
                }
                (false, None) => Reduction::Max { argmin: None },
            };
            T::storage(edge_backward::<T>(ab, bias, grad, &self.graph, rows, c, reduction))
        });
        Ok((out, Shape::from((rows, 2 * c))))
    }
}

// ---------------------------------------------------------------------------------------------
// Dropout

/// Inverted dropout whose mask is never stored: element `e` (in row-major order) is multiplied
/// by 0 when the `e`-th uniform draw of `start`'s stream is below `p`, else by `scale` (an
/// `f32`, as the mask's values). SplitMix64's stream is random-access
/// ([`SeededRng::ahead`]), so the elements are drawn in parallel, and the backward pass draws
/// the same mask again and applies it to the gradient.
pub(crate) struct Dropout {
    pub(crate) start: SeededRng,
    pub(crate) p: f64,
    pub(crate) scale: f32,
}

impl Dropout {
    fn apply<T: Elem>(&self, x: &[T]) -> Vec<T> {
        let keep = T::from_f32(self.scale);
        // `uniform() < p` in integers: a draw's top 53 bits m give m·2⁻⁵³ < p exactly when
        // m < ⌈p·2⁵³⌉ (scaling by a power of two is exact).
        let below = (self.p * (1u64 << 53) as f64).ceil() as u64;
        let mut out = vec![T::ZERO; x.len()];
        out.par_chunks_mut(DROPOUT_CHUNK)
            .zip(x.par_chunks(DROPOUT_CHUNK))
            .enumerate()
            .for_each(|(chunk, (out, x))| {
                let mut r = self.start.ahead((chunk * DROPOUT_CHUNK) as u64);
                // The factor is looked up, not branched on: the draws are coin flips, which a
                // branch predictor misses half the time.
                let factor = [T::ZERO, keep];
                for (o, &v) in out.iter_mut().zip(x) {
                    *o = v * factor[usize::from((r.next_u64() >> 11) >= below)];
                }
            });
        out
    }
}

/// Elements of a dropout one task draws.
pub(crate) const DROPOUT_CHUNK: usize = 1 << 14;

impl CustomOp1 for Dropout {
    fn name(&self) -> &'static str {
        "dropout"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> candle_core::Result<(CpuStorage, Shape)> {
        let out = dispatch!(s, T => T::storage(self.apply::<T>(T::slice(s, l, "dropout input")?)));
        Ok((out, l.shape().clone()))
    }

    fn bwd(
        &self,
        _arg: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> candle_core::Result<Option<Tensor>> {
        // The same op on the gradient: the same mask, drawn again.
        Ok(Some(grad.contiguous()?.apply_op1_no_bwd(self)?))
    }
}

// ---------------------------------------------------------------------------------------------
// Global pooling

/// The maximum over the points of each set: `(B, N, C)` → `(B, C)`. The gradient goes to the
/// first point (lowest index) that attains each maximum.
pub(crate) struct MaxOverPoints;

/// Gradient of [`MaxOverPoints`]: `(B, N, C)` input and `(B, C)` gradient → `(B, N, C)`.
struct MaxOverPointsBackward;

fn argmax_over_points<T: Elem>(x: &[T], n: usize, c: usize, set: usize) -> Vec<usize> {
    let base = set * n * c;
    let mut arg = vec![0usize; c];
    let mut best: Vec<T> = x[base..base + c].to_vec();
    for p in 1..n {
        let row = &x[base + p * c..base + (p + 1) * c];
        for ((b, a), &v) in best.iter_mut().zip(arg.iter_mut()).zip(row) {
            if v > *b {
                *b = v;
                *a = p;
            }
        }
    }
    arg
}

impl CustomOp1 for MaxOverPoints {
    fn name(&self) -> &'static str {
        "max-over-points"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> candle_core::Result<(CpuStorage, Shape)> {
        let (b, n, c) = l.shape().dims3()?;
        if n == 0 {
            candle_core::bail!("max-over-points: empty point sets");
        }
        let out = dispatch!(s, T => {
            let x = T::slice(s, l, "features")?;
            let mut out = vec![T::ZERO; b * c];
            out.par_chunks_mut(c).enumerate().for_each(|(set, o)| {
                for (ch, p) in argmax_over_points(x, n, c, set).into_iter().enumerate() {
                    o[ch] = x[(set * n + p) * c + ch];
                }
            });
            T::storage(out)
        });
        Ok((out, Shape::from((b, c))))
    }

    fn bwd(
        &self,
        arg: &Tensor,
        _res: &Tensor,
        grad: &Tensor,
    ) -> candle_core::Result<Option<Tensor>> {
        Ok(Some(arg.apply_op2_no_bwd(
            &grad.contiguous()?,
            &MaxOverPointsBackward,
        )?))
    }
}

impl CustomOp2 for MaxOverPointsBackward {
    fn name(&self) -> &'static str {
        "max-over-points-backward"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> candle_core::Result<(CpuStorage, Shape)> {
        let (b, n, c) = l1.shape().dims3()?;
        if l2.shape().dims2()? != (b, c) {
            candle_core::bail!("max-over-points-backward: gradient must be (B, C)");
        }
        let out = dispatch!(s1, T => {
            let x = T::slice(s1, l1, "features")?;
            let g = T::slice(s2, l2, "gradient")?;
            let mut out = vec![T::ZERO; b * n * c];
            out.par_chunks_mut(n * c).enumerate().for_each(|(set, o)| {
                for (ch, p) in argmax_over_points(x, n, c, set).into_iter().enumerate() {
                    o[p * c + ch] = g[set * c + ch];
                }
            });
            T::storage(out)
        });
        Ok((out, Shape::from((b, n, c))))
    }
}

#[cfg(test)]
mod tests;
