//! Small SVG figures written by hand: text needs no font files, and any browser shows them.

use std::fmt::Write as _;

use crate::contact_eval::{PlateRegion, PlateRegionStat, PlateRegions};

/// Grouped bars of the per-region plate errors (Table 2's summary): DGCNN and `KNN[All]` per
/// region, mean with ±sd whiskers, in mm. A mean that is not finite (no trial of the region
/// found contact) draws no bar.
pub fn region_bars(regions: &PlateRegions) -> String {
    type Method = (
        fn(&PlateRegion) -> &PlateRegionStat,
        &'static str,
        &'static str,
    );
    let methods: [Method; 2] = [
        (|r| &r.dgcnn, "DGCNN (SR-ARAP)", "#d62728"),
        (|r| &r.knn_all, "KNN[All]", "#1f77b4"),
    ];
    let finite = |v: f64| Some(v).filter(|v| v.is_finite());
    let top = regions
        .in_order()
        .into_iter()
        .flat_map(|(_, r)| methods.iter().map(move |m| m.0(r)))
        .filter_map(|stat| Some(finite(stat.mean_mm)? + finite(stat.sd_mm).unwrap_or(0.0)))
        .fold(1.0_f64, f64::max);
    // A round axis maximum.
    let step = if top > 20.0 {
        5.0
    } else if top > 8.0 {
        2.0
    } else {
        1.0
    };
    let y_max = (top / step).ceil() * step;
    let (w, h, left, bottom, top_pad) = (520.0, 340.0, 60.0, 50.0, 40.0);
    let plot_h = h - bottom - top_pad;
    let y = |v: f64| top_pad + plot_h * (1.0 - v / y_max);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="20" text-anchor="middle" font-size="14">Plate contacts: UCD predicted → true (mm), mean ± sd over trials</text>"#,
        w / 2.0
    );
    let mut v = 0.0;
    while v <= y_max + 1e-9 {
        let _ = writeln!(
            s,
            r##"<line x1="{left}" x2="{}" y1="{yy:.1}" y2="{yy:.1}" stroke="#ddd"/><text x="{}" y="{:.1}" text-anchor="end">{v}</text>"##,
            w - 20.0,
            left - 6.0,
            y(v) + 4.0,
            yy = y(v)
        );
        v += step;
    }
    let group = (w - left - 20.0) / regions.in_order().len() as f64;
    let bar = group / 4.0;
    for (i, (name, region)) in regions.in_order().into_iter().enumerate() {
        let x0 = left + group * i as f64 + group / 2.0 - bar;
        for (j, (stat, _, colour)) in methods.iter().enumerate() {
            let x = x0 + bar * j as f64;
            let stat = stat(region);
            if let Some(mean) = finite(stat.mean_mm) {
                let _ = writeln!(
                    s,
                    r#"<rect x="{x:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="{colour}"/>"#,
                    y(mean),
                    bar * 0.9,
                    y(0.0) - y(mean)
                );
                let sd = finite(stat.sd_mm).unwrap_or(0.0);
                let cx = x + bar * 0.45;
                let _ = writeln!(
                    s,
                    r#"<line x1="{cx:.1}" x2="{cx:.1}" y1="{:.1}" y2="{:.1}" stroke="black"/><text x="{cx:.1}" y="{:.1}" text-anchor="middle" font-size="10">{mean:.1}</text>"#,
                    y((mean - sd).max(0.0)),
                    y(mean + sd),
                    y(mean + sd) - 4.0
                );
            }
        }
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{name}</text>"#,
            left + group * (i as f64 + 0.5),
            h - bottom + 18.0
        );
    }
    let _ = writeln!(
        s,
        r#"<line x1="{left}" x2="{left}" y1="{top_pad}" y2="{:.1}" stroke="black"/>"#,
        y(0.0)
    );
    for (j, (_, label, colour)) in methods.iter().enumerate() {
        let x = left + 20.0 + 170.0 * j as f64;
        let _ = writeln!(
            s,
            r#"<rect x="{x}" y="{:.1}" width="12" height="12" fill="{colour}"/><text x="{}" y="{:.1}">{label}</text>"#,
            h - 22.0,
            x + 18.0,
            h - 12.0
        );
    }
    s.push_str("</svg>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bars_scale_to_the_largest_error_and_skip_missing_values() {
        let stat = |mean_mm: f64, sd_mm: f64| PlateRegionStat {
            mean_mm,
            sd_mm,
            trials: 3,
            trials_all_missed: 0,
        };
        let region = |dgcnn, knn_all| PlateRegion { dgcnn, knn_all };
        let regions = PlateRegions {
            tip: region(stat(3.0, 0.5), stat(3.5, 0.2)),
            middle: region(stat(7.0, 1.0), stat(13.5, 2.0)),
            base: region(stat(f64::NAN, f64::NAN), stat(20.0, 1.0)),
        };
        let svg = region_bars(&regions);
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        // Five bars (one value is missing) and a 25 mm axis (21 rounded up to a step of 5).
        assert_eq!(svg.matches("<rect x=").count(), 5 + 2, "{svg}");
        assert!(svg.contains(">25</text>") && !svg.contains(">30</text>"));
        assert!(svg.contains(">tip</text>") && svg.contains(">base</text>"));
    }
}
