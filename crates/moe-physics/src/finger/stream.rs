//! Stream memory: what one observation of a stream passes to the next — the press held (its
//! loads and place), the belief that the finger is pressed, the markers seen, and the contact
//! residual whose lag is taken out.

use moe_geom::{Point3, Real, Vector3};

use super::depth::DepthRow;
use super::gauss_newton::Solved;
use super::{FingerInverse, FingerObservation};

/// The previous frame's loads, to start from.
#[derive(Debug, Clone)]
pub(super) struct Tracked {
    pub(super) x: Vec<Point3>,
    pub(super) loads: Vec<(usize, Vector3)>,
}

/// The part of an observation that contact moves (observed minus free), kept for the next
/// observation's lag: per marker slot, and per depth patch as a point-to-plane distance.
#[derive(Debug, Clone)]
pub(super) struct LagResidual {
    time_secs: Real,
    markers: Vec<Option<Vector3>>,
    depth: Vec<(u32, Real)>,
}

/// With memory of a press's place, the probability that the next observation's press is a new
/// one, anywhere on the finger.
const NEW_PLACE_PROBABILITY: Real = 0.05;

impl FingerInverse {
    /// The log-odds, before this observation's evidence, that the finger is pressed: even odds
    /// without memory or at a stream's first observation. In a stream with `press_hold_secs`
    /// τ, a press believed with probability `p` at the previous observation persists over `Δt`
    /// with probability `a = exp(−Δt/τ)` and is otherwise as likely as not, and a free finger
    /// may be pressed at any observation as likely as not (onsets are not delayed):
    /// `p·(a + (1 − a)/2) + (1 − p)/2 = 1/2 + p·a/2`.
    pub(super) fn press_prior_logit(&self, obs: &FingerObservation<'_>, stream: bool) -> Real {
        let tau = self.config.press_hold_secs;
        match (self.press_belief, obs.time_secs) {
            (Some((t0, p)), Some(t)) if tau > 0.0 && stream && t > t0 => {
                let a = (-(t - t0) / tau).exp();
                let prior = (0.5 + 0.5 * p * a).min(1.0 - 1e-12);
                (prior / (1.0 - prior)).ln()
            }
            _ => 0.0,
        }
    }

    /// The place prior `prior` (area-weighted when `None`) with the evidence of lost markers
    /// (per slot, the weight `k` of its evidence; 0 for a marker seen, or not lost): a marker
    /// the camera loses is most often hidden by the object pressing the finger there, so places
    /// within `hidden_marker_radius_m` of a lost marker are made `1 + k` times as likely (a
    /// Gaussian falloff; the strongest marker's where several reach). Unchanged without
    /// evidence.
    fn with_hidden_markers(&self, prior: Option<Vec<Real>>, lost: &[Real]) -> Option<Vec<Real>> {
        let hidden: Vec<(Point3, Real)> = lost
            .iter()
            .zip(&self.markers)
            .filter(|(k, _)| **k > 0.0)
            .map(|(&k, &v)| (self.rest_surface[v as usize], k))
            .collect();
        if hidden.is_empty() {
            return prior;
        }
        let s2 = 2.0 * self.config.hidden_marker_radius_m.powi(2);
        self.reweighted(prior, |c| {
            let p = self.rest_surface[self.candidates[c] as usize];
            let near: Real = hidden
                .iter()
                .map(|(h, k)| k * (-(p - h).norm_squared() / s2).exp())
                .fold(0.0, Real::max);
            1.0 + near
        })
    }

    /// `prior` (area-weighted without one) times `weight` per candidate, normalised; `prior`
    /// itself when the product cannot be normalised.
    fn reweighted(
        &self,
        prior: Option<Vec<Real>>,
        weight: impl Fn(usize) -> Real,
    ) -> Option<Vec<Real>> {
        let mut out: Vec<Real> = (0..self.candidates.len())
            .map(|c| {
                let base = match &prior {
                    Some(prior) => prior[c],
                    None => self.area[self.candidates[c] as usize],
                };
                base * weight(c)
            })
            .collect();
        let total: Real = out.iter().sum();
        if total.is_finite() && total > 0.0 {
            out.iter_mut().for_each(|w| *w /= total);
            Some(out)
        } else {
            prior
        }
    }

    /// The prior over the candidates of a press in this observation from the previous one's
    /// posterior `memory`: each candidate's probability spread by a Gaussian step of
    /// `place_memory_m` on the rest surface, mixed with a new press anywhere (area-weighted)
    /// with probability [`NEW_PLACE_PROBABILITY`].
    fn propagate(&self, memory: &[Real]) -> Vec<Real> {
        let s2 = 2.0 * self.config.place_memory_m.powi(2);
        let position = |c: usize| self.rest_surface[self.candidates[c] as usize];
        let area = |c: usize| self.area[self.candidates[c] as usize];
        let total_area: Real = (0..self.candidates.len()).map(area).sum();
        let peak = memory.iter().copied().fold(0.0, Real::max);
        let mut prior: Vec<Real> = (0..self.candidates.len())
            .map(|c| NEW_PLACE_PROBABILITY * area(c) / total_area)
            .collect();
        let mut kernel = vec![0.0; self.candidates.len()];
        for (from, &m) in memory.iter().enumerate() {
            if m <= 1e-9 * peak {
                continue;
            }
            let p = position(from);
            let mut sum = 0.0;
            for (c, k) in kernel.iter_mut().enumerate() {
                *k = (-(position(c) - p).norm_squared() / s2).exp();
                sum += *k;
            }
            let share = (1.0 - NEW_PLACE_PROBABILITY) * m / sum;
            for (q, k) in prior.iter_mut().zip(&kernel) {
                *q += share * k;
            }
        }
        let total: Real = prior.iter().sum();
        prior.iter_mut().for_each(|q| *q /= total);
        prior
    }

    /// Markers and depth observations with the lag of the contact response taken out. The part
    /// of an observation that contact moves, `r = m − m_free` (a marker's offset, or a depth
    /// patch's mean point-to-plane distance), follows its static value `u` with the body's
    /// damping time `β` (a first-order lag); for `u` held over the interval since the previous
    /// observation, `r_t = a r_{t−1} + (1 − a) u` with `a = exp(−Δt/β)`, so
    /// `u = (r_t − a r_{t−1}) / (1 − a)`, taken with the configured gain. A depth patch not seen
    /// in the previous observation is left as measured. `None` without a previous residual in
    /// the stream.
    pub(super) fn contact_lag_corrected(
        &mut self,
        obs: &FingerObservation<'_>,
        x_free: &[Point3],
    ) -> Option<(Vec<Option<Point3>>, Vec<DepthRow>)> {
        let gain = self.config.contact_lag_gain;
        if !(gain > 0.0 && self.beta > 0.0) {
            self.previous_residual = None;
            return None;
        }
        let residual: Vec<Option<Vector3>> = obs
            .markers
            .iter()
            .zip(&self.markers)
            .map(|(m, &v)| m.map(|p| p - self.mech.surface_position(x_free, v)))
            .collect();
        let depth: Vec<(u32, Real)> = obs
            .depth
            .iter()
            .map(|row| {
                (
                    row.patch,
                    (row.value - self.depth_predicted(x_free, row)) / row.unit,
                )
            })
            .collect();
        let previous = self.previous_residual.take();
        self.previous_residual = obs.time_secs.map(|time_secs| LagResidual {
            time_secs,
            markers: residual.clone(),
            depth: depth.clone(),
        });
        let (t, previous) = (obs.time_secs?, previous?);
        let dt = t - previous.time_secs;
        if !(dt > 0.0 && dt <= self.config.stream_reach_secs()) {
            return None;
        }
        let a = (-dt / self.beta).exp();
        // The change that takes the lag out of a residual `r` whose previous value was `r0`.
        let unlag = |r: Real, r0: Real| ((r - r0 * a) / (1.0 - a) - r) * gain;
        // The previous residual: while a press is held, the previous estimate's dent, which
        // is the measured one without its noise and gives each depth patch's residual over this
        // observation's pixels; otherwise the previous observation's.
        let dent = self.previous_dent.as_deref();
        let previous_markers: Vec<Option<Vector3>> = match dent {
            Some(d) => self.markers.iter().map(|&v| Some(d[v as usize])).collect(),
            None => previous.markers,
        };
        let markers = obs
            .markers
            .iter()
            .zip(residual.iter().zip(&previous_markers))
            .map(|(m, (r, r0))| {
                let (p, r) = (m.as_ref()?, r.as_ref()?);
                Some(match r0 {
                    Some(r0) => p + r.zip_map(r0, unlag),
                    None => *p,
                })
            })
            .collect();
        let rows = obs
            .depth
            .iter()
            .zip(&depth)
            .map(|(row, &(patch, d))| {
                let d0 = match dent {
                    Some(dent) => Some(
                        row.terms
                            .iter()
                            .map(|(v, a)| a.dot(&dent[*v as usize]))
                            .sum::<Real>()
                            / row.unit,
                    ),
                    None => previous
                        .depth
                        .iter()
                        .find(|(q, _)| *q == patch)
                        .map(|q| q.1),
                };
                match d0 {
                    Some(d0) => DepthRow {
                        value: row.value + row.unit * unlag(d, d0),
                        ..row.clone()
                    },
                    None => row.clone(),
                }
            })
            .collect();
        Some((markers, rows))
    }

    /// Sets this observation's place prior from the remembered press and the hidden markers.
    pub(super) fn update_place_prior(&mut self, obs: &FingerObservation<'_>, dynamic: bool) {
        // The place's prior: the previous press, while the stream goes on.
        let memory = self.place_memory.take();
        let remembered = match memory {
            Some(m) if dynamic && self.config.place_memory_m > 0.0 => Some(self.propagate(&m)),
            _ => None,
        };
        // Markers seen earlier in the stream and hidden now: the marker history's evidence.
        if !dynamic || self.seen_in_stream.len() != obs.markers.len() {
            self.seen_in_stream = vec![false; obs.markers.len()];
        }
        // With a depth image, a lost marker with an object just in front of it is evidence of
        // its own weight, one the object is far from (passing between the camera and the
        // finger) none; without one, every lost marker is evidence.
        let depth = obs.covered.len() == obs.markers.len();
        let lost: Vec<Real> = obs
            .markers
            .iter()
            .zip(&self.seen_in_stream)
            .enumerate()
            .map(|(slot, (m, &seen))| match (m.is_none() && seen, depth) {
                (false, _) => 0.0,
                (true, false) => self.config.hidden_marker_prior,
                (true, true) if obs.covered[slot] => self
                    .config
                    .depth
                    .covered_marker_prior
                    .max(self.config.hidden_marker_prior),
                (true, true) => self.config.hidden_marker_prior,
            })
            .collect();
        for (seen, m) in self.seen_in_stream.iter_mut().zip(obs.markers) {
            *seen |= m.is_some();
        }
        let prior = self.with_hidden_markers(remembered, &lost);
        self.place_prior = self.with_seen_through(prior, obs.seen_through);
    }

    /// `prior` (area-weighted without one) with the candidates whose toucher's place the depth
    /// image sees through made [`crate::DepthSettings::seen_through_prior`] times as likely, and
    /// normalised. Unchanged when none is seen through or the test is off.
    pub(super) fn with_seen_through(
        &self,
        prior: Option<Vec<Real>>,
        seen: &[bool],
    ) -> Option<Vec<Real>> {
        let factor = self.config.depth.seen_through_prior;
        if factor >= 1.0 || seen.len() != self.candidates.len() || !seen.contains(&true) {
            return prior;
        }
        self.reweighted(prior, |c| if seen[c] { factor } else { 1.0 })
    }

    /// Remembers the press for the next observation: its place (one load only) and its loads.
    pub(super) fn remember_press(&mut self, mut posteriors: Vec<Vec<Real>>, state: &Solved) {
        // One press in a stream is remembered; two, or none, are not.
        self.place_memory = match posteriors.pop() {
            Some(p)
                if self.config.place_memory_m > 0.0 && posteriors.is_empty() && !p.is_empty() =>
            {
                Some(p)
            }
            _ => None,
        };
        self.tracked = Some(Tracked {
            x: state.x.clone(),
            loads: state.loads.clone(),
        });
    }
}
