//! Tendons: cables routed as polylines through the body, embedded barycentrically, driven by a
//! pulled length (displacement) or a tension (force), pull-only.
//!
//! A cable of tension `T` through points `p_0 … p_n` with unit segment directions
//! `u_k = (p_{k+1} − p_k)/ℓ_k` pushes point `k` with `f_k = T (u_k − u_{k−1})` (`u_{−1} = u_n = 0`):
//! `f_k = −T ∂L/∂p_k` with `L = Σ ℓ_k` its path length. In displacement mode the tension is a
//! stiff penalty `T = k_t · max(0, L − (L₀ + s − pull))` (slack when the path is shorter than
//! the rest length plus the cable's slack `s` ([`TendonParams::slack_m`], 0 by default) minus
//! the pull; a negative pull pays cable out), treated implicitly as a unilateral rank-one term;
//! in force mode `T` is given. Both add the cable's geometric stiffness `(T/ℓ_k)(I − u_k u_kᵀ)`
//! between consecutive points.

use moe_geom::{Matrix3, Point3, Real, TendonRoute, Vector3};
use serde::{Deserialize, Serialize};

use crate::embedding::{Embedded, Embedding};
use crate::error::{SimError, require_positive};
use crate::is_zero;
use crate::terms::{PairTerm, PointTerm, RankOneTerm, Terms};
use crate::tetmesh::TetMesh;

/// Tendon material.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TendonParams {
    /// Axial stiffness of a tendon in displacement mode, N/m (a nearly inextensible cable).
    /// Default 1e5.
    pub stiffness_n_per_m: Real,
    /// What a cable does at zero pull, in displacement mode: how much longer it is than its
    /// route at rest, metres. 0 (the default): held at its rest length by its motor, taut
    /// without tension, so it resists any bending that lengthens its path. Positive: slack by
    /// that length, taken up before the cable pulls (a pull of `slack_m + d` acts as a pull of
    /// `d` on a taut cable). Negative: pre-tensioned, stretched by that length at rest (tension
    /// `stiffness_n_per_m × −slack_m` before any pull).
    #[serde(skip_serializing_if = "is_zero")]
    pub slack_m: Real,
}

impl Default for TendonParams {
    fn default() -> Self {
        Self {
            stiffness_n_per_m: 1e5,
            slack_m: 0.0,
        }
    }
}

impl TendonParams {
    /// Checks the parameters.
    ///
    /// # Errors
    /// [`SimError::InvalidParameter`] for a non-positive stiffness or a non-finite slack.
    pub fn validate(&self) -> Result<(), SimError> {
        require_positive("tendon stiffness_n_per_m", self.stiffness_n_per_m)?;
        if !self.slack_m.is_finite() {
            return Err(SimError::InvalidParameter {
                name: "tendon slack_m",
                value: self.slack_m,
                reason: "must be finite",
            });
        }
        Ok(())
    }
}

/// What drives a tendon during one step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case")]
pub enum TendonCommand {
    /// Pulled length, metres (negative pays cable out).
    Displacement {
        /// Pulled length, metres.
        pull_m: Real,
    },
    /// Tension, newtons (≥ 0: a cable only pulls).
    Force {
        /// Tension, newtons.
        tension_n: Real,
    },
}

/// A tendon embedded in a body.
#[derive(Debug, Clone, PartialEq)]
pub struct Tendon {
    points: Vec<Embedded>,
    rest_length_m: Real,
    /// The distinct nodes of the embedded points, in order of first appearance: the entries of
    /// the length gradient.
    nodes: Vec<u32>,
    /// Per point and corner, the index in `nodes` of that corner's node.
    slots: Vec<[u32; 4]>,
}

/// State of a tendon after a step.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct TendonState {
    /// Current path length, metres.
    pub length_m: Real,
    /// Tension, newtons (0 when slack).
    pub tension_n: Real,
}

impl Tendon {
    /// Embeds route `index` (points in the body's rest frame) in `mesh`.
    ///
    /// # Errors
    /// [`SimError::TendonOutsideBody`] naming the first route point outside every element.
    pub fn new(mesh: &TetMesh, index: usize, route: &TendonRoute) -> Result<Self, SimError> {
        let emb = Embedding::new(mesh, &route.points_in_finger);
        if let Some(point) = emb.distances_m().iter().position(|&d| d > 0.0) {
            let p = route.points_in_finger[point];
            return Err(SimError::TendonOutsideBody {
                tendon: index,
                point,
                x: p.x,
                y: p.y,
                z: p.z,
            });
        }
        let points = emb.points().to_vec();
        let mut nodes: Vec<u32> = Vec::new();
        let mut slot_of = std::collections::HashMap::new();
        let slots = points
            .iter()
            .map(|e| {
                e.nodes.map(|node| {
                    *slot_of.entry(node).or_insert_with(|| {
                        nodes.push(node);
                        (nodes.len() - 1) as u32
                    })
                })
            })
            .collect();
        Ok(Self {
            points,
            rest_length_m: route.length(),
            nodes,
            slots,
        })
    }

    /// The embedded route points.
    pub fn points(&self) -> &[Embedded] {
        &self.points
    }

    /// Rest path length, metres.
    pub fn rest_length_m(&self) -> Real {
        self.rest_length_m
    }

    /// Number of distinct nodes the tendon's points are embedded in (the length of its
    /// rank-one gradient).
    pub(crate) fn num_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Unit direction and length of segment `k` (from point `k` to point `k + 1`; a zero
    /// direction for a zero-length segment).
    #[inline]
    fn segment(&self, x: &[Point3], k: usize) -> (Vector3, Real) {
        let d = self.points[k + 1].position(x) - self.points[k].position(x);
        let l = d.norm();
        (if l > 0.0 { d / l } else { Vector3::zeros() }, l)
    }

    /// Node pairs coupled by consecutive route points (for the system pattern).
    pub(crate) fn coupled_pairs(&self) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        for w in self.points.windows(2) {
            for a in w[0].nodes {
                for b in w[1].nodes {
                    out.push((a, b));
                }
            }
        }
        out
    }

    /// The path length beyond which a cable pulled by `pull_m` is in tension.
    fn held_length(&self, pull_m: Real, params: &TendonParams) -> Real {
        self.rest_length_m + params.slack_m - pull_m
    }

    /// Current path length for node positions `x`.
    pub fn length(&self, x: &[Point3]) -> Real {
        self.points
            .windows(2)
            .map(|w| (w[1].position(x) - w[0].position(x)).norm())
            .sum()
    }

    /// Tension for positions `x` under `command` (from the current length; 0 when slack).
    pub fn tension(&self, x: &[Point3], command: TendonCommand, params: &TendonParams) -> Real {
        match command {
            TendonCommand::Displacement { pull_m } => {
                let excess = self.length(x) - self.held_length(pull_m, params);
                params.stiffness_n_per_m * excess.max(0.0)
            }
            TendonCommand::Force { tension_n } => tension_n.max(0.0),
        }
    }

    /// Adds this tendon's terms for positions `x` to `terms` (without allocating once `terms`
    /// has room: the segment directions are recomputed where needed instead of stored): in
    /// displacement mode a unilateral rank-one term on the length excess, in force mode the
    /// cable forces, and in both the segments' geometric stiffness.
    pub fn add_terms(
        &self,
        x: &[Point3],
        command: TendonCommand,
        params: &TendonParams,
        terms: &mut Terms,
    ) {
        let n = self.points.len();
        let length: Real = (0..n - 1).map(|k| self.segment(x, k).1).sum();
        // ∂L/∂p_k = u_{k−1} − u_k.
        let grad_point = |k: usize| {
            let prev = if k > 0 {
                self.segment(x, k - 1).0
            } else {
                Vector3::zeros()
            };
            let next = if k < n - 1 {
                self.segment(x, k).0
            } else {
                Vector3::zeros()
            };
            prev - next
        };
        let tension = match command {
            TendonCommand::Displacement { pull_m } => {
                let excess = length - self.held_length(pull_m, params);
                // Contributions are summed per node in point order; −0 is the exact identity of
                // floating-point addition, so each sum starts from its first contribution.
                let mut gradient = terms.gradient_buffer();
                gradient.extend(self.nodes.iter().map(|&node| (node, Vector3::repeat(-0.0))));
                for (k, (e, slots)) in self.points.iter().zip(&self.slots).enumerate() {
                    let g = grad_point(k);
                    for j in 0..4 {
                        gradient[slots[j] as usize].1 += g * e.weights[j];
                    }
                }
                terms.rank_ones.push(RankOneTerm {
                    gradient,
                    stiffness: params.stiffness_n_per_m,
                    value: excess,
                    unilateral: true,
                });
                params.stiffness_n_per_m * excess.max(0.0)
            }
            TendonCommand::Force { tension_n } => {
                let t = tension_n.max(0.0);
                // The cable's potential: its tension times its length.
                terms.point_energy_j += t * length;
                if t > 0.0 {
                    for (k, e) in self.points.iter().enumerate() {
                        terms.points.push(PointTerm {
                            point: *e,
                            force: -grad_point(k) * t,
                            stiffness: Matrix3::zeros(),
                            damping: Matrix3::zeros(),
                            target_velocity: Vector3::zeros(),
                        });
                    }
                }
                t
            }
        };
        if tension > 0.0 {
            for k in 0..n - 1 {
                let (u, len) = self.segment(x, k);
                if len > 0.0 {
                    terms.pairs.push(PairTerm {
                        a: self.points[k],
                        b: self.points[k + 1],
                        stiffness: (Matrix3::identity() - u * u.transpose()) * (tension / len),
                    });
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_cable_parameters_are_named() {
        for (params, name) in [
            (
                TendonParams {
                    stiffness_n_per_m: 0.0,
                    ..TendonParams::default()
                },
                "tendon stiffness_n_per_m",
            ),
            (
                TendonParams {
                    slack_m: Real::NAN,
                    ..TendonParams::default()
                },
                "tendon slack_m",
            ),
        ] {
            match params.validate() {
                Err(SimError::InvalidParameter { name: got, .. }) => assert_eq!(got, name),
                other => panic!("{name}: expected an error, got {other:?}"),
            }
        }
        TendonParams::default().validate().unwrap();
        // A default cable writes no slack field: files written before it read the same.
        let text = serde_json::to_string(&TendonParams::default()).unwrap();
        assert!(!text.contains("slack"), "{text}");
    }
}
