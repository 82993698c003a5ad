//! `moe-touch eval observability`: how well a marker layout lets the physics estimator locate
//! a press, whatever the estimator — the Cramér–Rao bound of the press's place along and around
//! the finger and of its force (`moe_physics::PhysicsEstimator::location_bounds`), at every
//! movable surface vertex of finger 0 of the two-finger hand (default finger, default material
//! and settings, zero pulls, gravity along the hand's −z), for each layout of the study: the
//! camera row of 7 (the paper's), two rows of 7 at ±35°, the camera row and rows of 7 on the
//! sides (±90°), and the camera row with a ring of 6 at the tip. Per layout and region (tip
//! z > 80 % of the length with the cap, middle 40–70 %, base 12–35 %): median and 90th
//! percentile, for one frame and for `--frames` frames of a held press (independent marker
//! noise per frame: the bound over √N). With `--out DIR`: `DIR/bound_map.svg`, each layout's
//! surface unrolled (angle around the axis, camera side at 0°, against height) with every
//! vertex coloured by its along-axis bound on a shared log scale and the markers as black
//! rings, and `DIR/observability.json`, the summary.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use moe_geom::{
    FingerModel, FingerParams, HandModel, HandPreset, MarkerLayoutPreset, Point3, Real, Vector3,
};
use moe_physics::{
    BoundOptions, HandMaterial, PhysicsConfig, PhysicsEstimator, PlaceBound, RegionBound, quantile,
    region_bounds,
};
use serde::Serialize;

/// Arguments of `moe-touch eval observability`.
#[derive(Debug, Args)]
pub(crate) struct ObservabilityEvalArgs {
    /// Write `DIR/bound_map.svg` (the bound on every layout's unrolled surface) and
    /// `DIR/observability.json`.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Frames of the held press of the second summary (the first is one frame).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(2..=10_000))]
    frames: u64,
    /// Force of the press, newtons.
    #[arg(long, value_name = "N", default_value_t = BoundOptions::default().force_n)]
    force: Real,
    /// Noise of a marker coordinate, metres (default: the perception stage's, 0.16 mm).
    #[arg(long, value_name = "M", default_value_t = BoundOptions::default().marker_sigma_m)]
    sigma: Real,
    /// Print one JSON object on stdout instead of tables.
    #[arg(long)]
    json: bool,
}

/// Sides of the finger at mid height (40–70 % of the length): name and the range of the
/// angle's magnitude around the axis from the camera side, degrees.
const SIDES: [(&str, Real, Real); 3] = [
    ("camera", 0.0, 45.0),
    ("flanks", 45.0, 135.0),
    ("back", 135.0, 180.0),
];

/// One layout's bound for one number of frames.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct LayoutSummary {
    pub(crate) layout: &'static str,
    pub(crate) markers: usize,
    pub(crate) frames: usize,
    pub(crate) regions: Vec<RegionBound>,
    /// At mid height, by side: median along and around bounds, mm.
    pub(crate) mid_height_by_side: Vec<SideSummary>,
}

/// The median bound on one side of the finger at mid height.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub(crate) struct SideSummary {
    pub(crate) side: &'static str,
    pub(crate) vertices: usize,
    pub(crate) along_mm_median: Real,
    pub(crate) around_mm_median: Real,
}

/// A layout's finger and its bound at every movable vertex.
pub(crate) struct LayoutBounds {
    pub(crate) layout: MarkerLayoutPreset,
    pub(crate) finger: FingerModel,
    pub(crate) bounds: Vec<PlaceBound>,
}

/// The finger of the study with `layout`.
pub(crate) fn study_params(layout: MarkerLayoutPreset) -> FingerParams {
    FingerParams {
        marker_layout: layout.layout(),
        ..FingerParams::default()
    }
}

/// The bound of every movable vertex of finger 0 of the two-finger hand with `layout`.
pub(crate) fn layout_bounds(
    layout: MarkerLayoutPreset,
    options: &BoundOptions,
) -> Result<LayoutBounds> {
    let hand = HandModel::preset(HandPreset::TwoFinger, &study_params(layout))?;
    let one = HandModel::new(vec![hand.fingers()[0].clone()])?;
    let config = PhysicsConfig::default();
    let mut estimator = PhysicsEstimator::new(&one, &HandMaterial::default(), &config)?;
    let gravity = Vector3::new(0.0, 0.0, -Vector3::from(config.gravity_m_s2).norm());
    let finger = one.fingers()[0].model.clone();
    let pulls = vec![0.0; finger.tendon_routes().len()];
    let bounds = estimator
        .location_bounds(0, &pulls, gravity, options)
        .with_context(|| format!("the bound of the {layout} layout"))?;
    Ok(LayoutBounds {
        layout,
        finger,
        bounds,
    })
}

/// Angle of a point around the finger's axis from the camera side (+x), degrees, −180 to 180.
fn angle_deg(p: &Point3) -> Real {
    p.y.atan2(p.x).to_degrees()
}

impl LayoutBounds {
    /// The finger's length (its highest rest vertex).
    fn length(&self) -> Real {
        self.finger
            .mesh()
            .vertices()
            .iter()
            .map(|p| p.z)
            .fold(Real::MIN, Real::max)
    }

    /// The bounds whose vertex lies between heights `lo` and `hi` (fractions of the length).
    fn in_band(&self, lo: Real, hi: Real) -> impl Iterator<Item = &PlaceBound> {
        let length = self.length();
        self.bounds
            .iter()
            .filter(move |b| (lo..=hi).contains(&(b.rest_in_finger.z / length)))
    }

    /// The summary per region and, at mid height, per side.
    pub(crate) fn summary(&self, frames: usize) -> LayoutSummary {
        let regions = region_bounds(&self.bounds, self.length());
        let mid_height_by_side = SIDES
            .iter()
            .map(|&(side, lo, hi)| {
                let on: Vec<&PlaceBound> = self
                    .in_band(0.4, 0.7)
                    .filter(|b| (lo..=hi).contains(&angle_deg(&b.rest_in_finger).abs()))
                    .collect();
                let med = |f: fn(&PlaceBound) -> Real| {
                    quantile(&on.iter().map(|b| f(b)).collect::<Vec<_>>(), 0.5)
                };
                SideSummary {
                    side,
                    vertices: on.len(),
                    along_mm_median: med(|b| b.along_m * 1e3),
                    around_mm_median: med(|b| b.around_m * 1e3),
                }
            })
            .collect();
        LayoutSummary {
            layout: self.layout.name(),
            markers: self.finger.marker_vertices().len(),
            frames,
            regions,
            mid_height_by_side,
        }
    }
}

/// The whole report.
#[derive(Debug, Serialize)]
struct Report {
    force_n: Real,
    marker_sigma_m: Real,
    pulls: &'static str,
    gravity: &'static str,
    summaries: Vec<LayoutSummary>,
}

pub(crate) fn run(args: &ObservabilityEvalArgs) -> Result<()> {
    let one = BoundOptions {
        force_n: args.force,
        marker_sigma_m: args.sigma,
        frames: 1,
    };
    one.validate()?;
    let held_frames = args.frames as usize;
    BoundOptions {
        frames: held_frames,
        ..one.clone()
    }
    .validate()?;
    let mut layouts = Vec::new();
    let mut summaries = Vec::new();
    for layout in MarkerLayoutPreset::ALL {
        let single = layout_bounds(layout, &one)?;
        summaries.push(single.summary(1));
        let held = LayoutBounds {
            layout,
            finger: single.finger.clone(),
            bounds: single
                .bounds
                .iter()
                .map(|b| b.over_frames(args.frames as usize))
                .collect(),
        };
        summaries.push(held.summary(held_frames));
        eprintln!("eval observability: {layout} done");
        layouts.push(single);
    }
    let report = Report {
        force_n: one.force_n,
        marker_sigma_m: one.marker_sigma_m,
        pulls: "zero",
        gravity: "along the hand's -z",
        summaries,
    };
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        moe_io::write_atomic(
            &dir.join("bound_map.svg"),
            bound_map_svg(&layouts).as_bytes(),
        )?;
        moe_io::write_json(&dir.join("observability.json"), &report)?;
        eprintln!(
            "eval observability: wrote bound_map.svg and observability.json to {}",
            dir.display()
        );
    }
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{}", table(&report));
    }
    Ok(())
}

/// The report as Markdown tables.
fn table(r: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Cramér–Rao bound of a press's place on finger 0 of the two-finger hand: {:.2} N along the \
         inward normal, marker noise {:.3} mm per coordinate, zero pulls, gravity along −z; \
         median / 90th percentile over each region's movable vertices",
        r.force_n,
        r.marker_sigma_m * 1e3
    );
    let _ = writeln!(
        s,
        "\n| layout | markers | frames | region | along mm | around mm | force sd N |\n|---|---|---|---|---|---|---|"
    );
    for l in &r.summaries {
        for g in &l.regions {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {:.2} / {:.2} | {:.2} / {:.2} | {:.3} / {:.3} |{}",
                l.layout,
                l.markers,
                l.frames,
                g.region,
                g.along_mm.median,
                g.along_mm.p90,
                g.around_mm.median,
                g.around_mm.p90,
                g.force_sd_n.median,
                g.force_sd_n.p90,
                if g.unobservable > 0 {
                    format!(" {} unobservable", g.unobservable)
                } else {
                    String::new()
                }
            );
        }
    }
    let _ = writeln!(
        s,
        "\nmid height (40–70 % of the length), one frame, median along / around mm by side \
         (angle from the camera side):\n\n| layout | camera (0–45°) | flanks (45–135°) | back (135–180°) |\n|---|---|---|---|"
    );
    for l in r.summaries.iter().filter(|l| l.frames == 1) {
        let cell = |k: usize| {
            let m = &l.mid_height_by_side[k];
            format!("{:.2} / {:.2}", m.along_mm_median, m.around_mm_median)
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} |",
            l.layout,
            cell(0),
            cell(1),
            cell(2)
        );
    }
    s
}

/// The figure's colour of `t` from 0 (dark blue: small bound) to 1 (yellow).
fn ramp(t: Real) -> String {
    let [r, g, b] = moe_io::viridis_colour(t);
    format!("#{r:02x}{g:02x}{b:02x}")
}

/// Ticks of a log scale from `lo` to `hi`: 1, 2, 5 × powers of ten.
fn log_ticks(lo: Real, hi: Real) -> Vec<Real> {
    let mut out = Vec::new();
    let mut decade = 10f64.powf(lo.log10().floor());
    while decade <= hi {
        for m in [1.0, 2.0, 5.0] {
            let v = m * decade;
            if v >= lo * 0.999 && v <= hi * 1.001 {
                out.push(v);
            }
        }
        decade *= 10.0;
    }
    out
}

/// The colour scale the panels share: from the smallest finite bound to the 95th percentile
/// (the few vertices next to the clamped base have bounds of metres; they share the top
/// colour), widened to 1-2-5 values, in mm.
struct BoundScale {
    lo: Real,
    hi: Real,
    /// Some bounds lie above `hi` (or are undefined).
    clipped: bool,
}

impl BoundScale {
    fn of(layouts: &[LayoutBounds]) -> Self {
        let finite: Vec<Real> = layouts
            .iter()
            .flat_map(|l| l.bounds.iter().map(|b| b.along_m * 1e3))
            .filter(|v| v.is_finite() && *v > 0.0)
            .collect();
        let lo_raw = finite.iter().copied().fold(Real::INFINITY, Real::min);
        let hi_raw = quantile(&finite, 0.95);
        let (lo, hi) = if lo_raw.is_finite() && hi_raw > lo_raw {
            let down = |v: Real| {
                let d = 10f64.powf(v.log10().floor());
                [5.0, 2.0, 1.0]
                    .iter()
                    .map(|m| m * d)
                    .find(|&t| t <= v)
                    .unwrap_or(d)
            };
            let up = |v: Real| {
                let d = 10f64.powf(v.log10().floor());
                [1.0, 2.0, 5.0, 10.0]
                    .iter()
                    .map(|m| m * d)
                    .find(|&t| t >= v)
                    .unwrap_or(10.0 * d)
            };
            (down(lo_raw), up(hi_raw))
        } else {
            (0.1, 100.0)
        };
        let clipped = layouts
            .iter()
            .flat_map(|l| &l.bounds)
            .any(|b| b.along_m.is_nan() || b.along_m * 1e3 > hi);
        Self { lo, hi, clipped }
    }

    /// Where `v` (mm) falls on the scale, 0 to 1 (undefined bounds at the top).
    fn t(&self, v: Real) -> Real {
        let (lo, hi) = (self.lo, self.hi);
        if v.is_finite() {
            ((v.max(lo).log10() - lo.log10()) / (hi.log10() - lo.log10())).min(1.0)
        } else {
            1.0
        }
    }
}

/// Panel sizes of the figure, px.
const PANEL_W: Real = 380.0;
const PANEL_H: Real = 330.0;
const LEGEND_H: Real = 70.0;

/// The figure: per layout, the finger's surface unrolled (x: angle around the axis, −180° to
/// 180° with the camera side at 0°; y: height, 0 to 80 mm), each movable vertex a dot coloured
/// by its along-axis bound on a log scale shared by the panels, the markers black rings; a
/// legend in mm.
pub(crate) fn bound_map_svg(layouts: &[LayoutBounds]) -> String {
    let scale = BoundScale::of(layouts);
    let cols = 2usize.min(layouts.len().max(1));
    let rows = layouts.len().div_ceil(cols).max(1);
    let (w, h) = (
        PANEL_W * cols as Real + 20.0,
        40.0 + PANEL_H * rows as Real + LEGEND_H,
    );
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="22" text-anchor="middle" font-size="14">Cramér–Rao bound of a press's place along the finger (mm), finger 0, one frame; markers: black rings</text>"#,
        w / 2.0
    );
    for (k, l) in layouts.iter().enumerate() {
        let origin = (
            10.0 + PANEL_W * (k % cols) as Real,
            40.0 + PANEL_H * (k / cols) as Real,
        );
        bound_panel(&mut s, origin, l, &scale);
    }
    bound_legend(&mut s, w, h, &scale);
    s.push_str("</svg>\n");
    s
}

/// One layout's panel, its top left corner at `(ox, oy)`.
fn bound_panel(s: &mut String, (ox, oy): (Real, Real), l: &LayoutBounds, scale: &BoundScale) {
    let (ml, mr, mt, mb) = (52.0, 16.0, 34.0, 40.0); // plot margins in a panel
    let height_mm = 80.0;
    let (x0, x1) = (ox + ml, ox + PANEL_W - mr);
    let (y0, y1) = (oy + mt, oy + PANEL_H - mb); // top, bottom of the plot
    let x = |deg: Real| x0 + (deg + 180.0) / 360.0 * (x1 - x0);
    let y = |z_m: Real| y1 - z_m * 1e3 / height_mm * (y1 - y0);
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="13">{} ({} markers)</text>"#,
        (x0 + x1) / 2.0,
        oy + 20.0,
        l.layout.name(),
        l.finger.marker_vertices().len()
    );
    // Grid and axes.
    for deg in [-180.0, -90.0, 0.0, 90.0, 180.0] {
        let _ = writeln!(
            s,
            r##"<line x1="{xx:.1}" x2="{xx:.1}" y1="{y0:.1}" y2="{y1:.1}" stroke="#ddd"/><text x="{xx:.1}" y="{:.1}" text-anchor="middle" font-size="10">{deg}°</text>"##,
            y1 + 14.0,
            xx = x(deg)
        );
    }
    for mm in [0.0, 20.0, 40.0, 60.0, 80.0] {
        let yy = y(mm * 1e-3);
        let _ = writeln!(
            s,
            r##"<line x1="{x0:.1}" x2="{x1:.1}" y1="{yy:.1}" y2="{yy:.1}" stroke="#ddd"/><text x="{:.1}" y="{:.1}" text-anchor="end" font-size="10">{mm}</text>"##,
            x0 - 4.0,
            yy + 3.5
        );
    }
    let _ = writeln!(
        s,
        r#"<rect x="{x0:.1}" y="{y0:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="black"/>"#,
        x1 - x0,
        y1 - y0
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="10">angle around the axis (camera side 0°, back ±180°)</text>"#,
        (x0 + x1) / 2.0,
        y1 + 28.0
    );
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle" font-size="10" transform="rotate(-90 {:.1} {:.1})">height (mm)</text>"#,
        ox + 14.0,
        (y0 + y1) / 2.0,
        ox + 14.0,
        (y0 + y1) / 2.0
    );
    // The vertices, then the markers on top.
    for b in &l.bounds {
        let p = b.rest_in_finger;
        let _ = writeln!(
            s,
            r#"<circle cx="{:.1}" cy="{:.1}" r="2.6" fill="{}"/>"#,
            x(angle_deg(&p)),
            y(p.z),
            ramp(scale.t(b.along_m * 1e3))
        );
    }
    for p in l.finger.marker_positions() {
        let _ = writeln!(
            s,
            r#"<circle class="marker" cx="{:.1}" cy="{:.1}" r="4.5" fill="none" stroke="black" stroke-width="1.6"/>"#,
            x(angle_deg(&p)),
            y(p.z)
        );
    }
}

/// The legend: a gradient bar with 1-2-5 ticks, across the bottom of a `w` × `h` figure.
fn bound_legend(s: &mut String, w: Real, h: Real, scale: &BoundScale) {
    let (lo, hi, clipped) = (scale.lo, scale.hi, scale.clipped);
    let (lx0, lx1, ly) = (w / 2.0 - 220.0, w / 2.0 + 220.0, h - LEGEND_H + 14.0);
    let _ = writeln!(
        s,
        r#"<defs><linearGradient id="ramp" x1="0" x2="1" y1="0" y2="0">"#
    );
    for k in 0..=8 {
        let t = k as Real / 8.0;
        let _ = writeln!(s, r#"<stop offset="{t:.3}" stop-color="{}"/>"#, ramp(t));
    }
    let _ = writeln!(s, "</linearGradient></defs>");
    let _ = writeln!(
        s,
        r#"<rect x="{lx0:.1}" y="{ly:.1}" width="{:.1}" height="14" fill="url(#ramp)" stroke="black"/>"#,
        lx1 - lx0
    );
    for v in log_ticks(lo, hi) {
        let xx = lx0 + scale.t(v) * (lx1 - lx0);
        let label = if clipped && v >= hi {
            format!("≥ {v}")
        } else {
            v.to_string()
        };
        let _ = writeln!(
            s,
            r#"<line x1="{xx:.1}" x2="{xx:.1}" y1="{:.1}" y2="{:.1}" stroke="black"/><text x="{xx:.1}" y="{:.1}" text-anchor="middle" font-size="10">{label}</text>"#,
            ly + 14.0,
            ly + 18.0,
            ly + 30.0
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">along-axis bound, mm (log scale)</text>"#,
        w / 2.0,
        ly + 48.0
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bound is finite everywhere on the paper's finger; at mid height it is larger on the
    /// flanks (±90°, away from the camera row's bending plane) than on the camera side, and
    /// rows on the flanks bring it down there; it shrinks as one over the square root of the
    /// frames of a held press. (The back is not worse than the camera side: a press there bends
    /// the finger in the same plane, which the row sees stretch and shorten.)
    #[test]
    fn the_bound_is_finite_worse_far_from_the_markers_and_falls_with_frames() {
        let one = BoundOptions::default();
        let row = layout_bounds(MarkerLayoutPreset::CameraRow, &one).unwrap();
        assert!(
            row.bounds.len() > 800,
            "{} movable vertices",
            row.bounds.len()
        );
        for b in &row.bounds {
            assert!(
                b.along_m.is_finite() && b.around_m.is_finite() && b.force_sd_n.is_finite(),
                "{b:?}"
            );
            assert!(b.along_m > 0.0 && b.around_m > 0.0 && b.force_sd_n > 0.0);
        }
        let s = row.summary(1);
        let side = |k: usize| &s.mid_height_by_side[k];
        assert!(side(0).vertices > 20 && side(1).vertices > 20);
        for (flank, camera, what) in [
            (side(1).along_mm_median, side(0).along_mm_median, "along"),
            (side(1).around_mm_median, side(0).around_mm_median, "around"),
        ] {
            assert!(
                flank > 1.3 * camera,
                "{what}: flanks {flank} mm vs camera side {camera} mm"
            );
        }
        let sides = layout_bounds(MarkerLayoutPreset::Sides, &one)
            .unwrap()
            .summary(1);
        assert!(
            sides.mid_height_by_side[1].along_mm_median < 0.5 * side(1).along_mm_median,
            "rows on the flanks: {} mm, the camera row alone: {} mm",
            sides.mid_height_by_side[1].along_mm_median,
            side(1).along_mm_median
        );
        let five = layout_bounds(
            MarkerLayoutPreset::CameraRow,
            &BoundOptions {
                frames: 5,
                ..one.clone()
            },
        )
        .unwrap();
        for (a, b) in row.bounds.iter().zip(&five.bounds) {
            assert_eq!(a.vertex, b.vertex);
            for (x1, x5) in [
                (a.along_m, b.along_m),
                (a.around_m, b.around_m),
                (a.force_sd_n, b.force_sd_n),
            ] {
                // Exactly √5 but for the rounding of the Fisher matrices' inverses, which are
                // ill-conditioned next to the clamped base.
                let ratio = x1 / x5;
                assert!((ratio / 5f64.sqrt() - 1.0).abs() < 1e-4, "{ratio}");
            }
            // What the study reports for five frames, scaled without solving again.
            let scaled = a.over_frames(5);
            assert_eq!(scaled.vertex, b.vertex);
            for (s5, x5) in [
                (scaled.along_m, b.along_m),
                (scaled.around_m, b.around_m),
                (scaled.force_sd_n, b.force_sd_n),
            ] {
                assert!((s5 / x5 - 1.0).abs() < 1e-4, "{s5} vs {x5}");
            }
        }
        // More markers around the finger: two rows locate a press around it better.
        let two = layout_bounds(MarkerLayoutPreset::TwoRows, &one)
            .unwrap()
            .summary(1);
        for (r2, r1) in two.regions.iter().zip(&s.regions) {
            assert!(
                r2.around_mm.median < r1.around_mm.median,
                "{}: two rows {} mm, one row {} mm",
                r1.region,
                r2.around_mm.median,
                r1.around_mm.median
            );
        }
    }

    #[test]
    fn the_figure_has_a_panel_per_layout_and_a_ring_per_marker() {
        let options = BoundOptions::default();
        let layouts: Vec<LayoutBounds> =
            [MarkerLayoutPreset::CameraRow, MarkerLayoutPreset::TipRing]
                .into_iter()
                .map(|l| layout_bounds(l, &options).unwrap())
                .collect();
        let svg = bound_map_svg(&layouts);
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        assert_eq!(svg.matches(r#"class="marker""#).count(), 7 + 13);
        assert!(svg.contains("camera-row (7 markers)") && svg.contains("tip-ring (13 markers)"));
        let dots = layouts.iter().map(|l| l.bounds.len()).sum::<usize>();
        assert_eq!(svg.matches("<circle cx=").count(), dots);
        assert!(svg.contains("along-axis bound, mm"));
    }

    #[test]
    fn log_ticks_are_one_two_five() {
        assert_eq!(log_ticks(0.5, 20.0), [0.5, 1.0, 2.0, 5.0, 10.0, 20.0]);
        assert_eq!(log_ticks(1.0, 1.0), [1.0]);
    }
}
