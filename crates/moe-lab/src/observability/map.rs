//! What `moe-touch eval observability` shows of the study: its tables as text and the bound
//! map, each layout's finger surface unrolled with every vertex coloured by its bound (SVG).

use std::fmt::Write as _;

use moe_geom::Real;
use moe_physics::quantile;

use super::{LayoutBounds, ObservabilityReport, angle_around_axis_deg};

impl ObservabilityReport {
    /// The report as the Markdown tables `moe-touch eval observability` prints: per layout,
    /// number of frames and region, the median / 90th percentile of the bounds; then, for one
    /// frame, the median bounds at mid height by side.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Cramér–Rao bound of a press's place on finger 0 of the two-finger hand: {:.2} N along the \
             inward normal, marker noise {:.3} mm per coordinate (the depth rows: the wrist camera's \
             depth noise model), zero pulls, gravity along −z; median / 90th percentile over each \
             region's movable vertices",
            self.force_n,
            self.marker_sigma_m * 1e3
        );
        let _ = writeln!(
            s,
            "\n| layout | markers | frames | region | along mm | around mm | force sd N |\n|---|---|---|---|---|---|---|"
        );
        for l in &self.summaries {
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
        for l in self.summaries.iter().filter(|l| l.frames == 1) {
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
}

/// The figure's colour of `t` from 0 (dark blue: small bound) to 1 (yellow).
fn ramp(t: Real) -> String {
    let [r, g, b] = moe_record::viridis_colour(t);
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
pub fn bound_map_svg(layouts: &[LayoutBounds]) -> String {
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
        l.observed,
        l.observed_markers
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
            x(angle_around_axis_deg(&p)),
            y(p.z),
            ramp(scale.t(b.along_m * 1e3))
        );
    }
    // Rings only for markers the bound observed (none on the depth-only panels).
    let observed = if l.observed_markers > 0 {
        l.finger.marker_positions()
    } else {
        Vec::new()
    };
    for p in observed {
        let _ = writeln!(
            s,
            r#"<circle class="marker" cx="{:.1}" cy="{:.1}" r="4.5" fill="none" stroke="black" stroke-width="1.6"/>"#,
            x(angle_around_axis_deg(&p)),
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
    use crate::observability::layout_bounds;
    use moe_geom::MarkerLayoutPreset;
    use moe_physics::BoundOptions;

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
