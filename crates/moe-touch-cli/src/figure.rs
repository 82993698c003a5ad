//! Small SVG figures written by hand: text needs no font files, and any browser shows them.

use std::fmt::Write as _;

/// Grouped bars of the per-region plate errors (`region_summary`'s JSON): DGCNN and `KNN[All]`
/// per region, mean with ±sd whiskers, in mm.
pub(crate) fn region_bars(summary: &serde_json::Value) -> String {
    let regions = ["tip", "middle", "base"];
    let methods = [
        ("dgcnn", "DGCNN (SR-ARAP)", "#d62728"),
        ("knn_all", "KNN[All]", "#1f77b4"),
    ];
    let value = |r: &str, m: &str, k: &str| summary[r][m][k].as_f64().filter(|v| v.is_finite());
    let top = regions
        .iter()
        .flat_map(|r| methods.iter().map(move |m| (r, m)))
        .filter_map(|(r, m)| {
            Some(value(r, m.0, "mean_mm")? + value(r, m.0, "sd_mm").unwrap_or(0.0))
        })
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
    let group = (w - left - 20.0) / regions.len() as f64;
    let bar = group / 4.0;
    for (i, r) in regions.iter().enumerate() {
        let x0 = left + group * i as f64 + group / 2.0 - bar;
        for (j, (key, _, colour)) in methods.iter().enumerate() {
            let x = x0 + bar * j as f64;
            if let Some(mean) = value(r, key, "mean_mm") {
                let _ = writeln!(
                    s,
                    r#"<rect x="{x:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="{colour}"/>"#,
                    y(mean),
                    bar * 0.9,
                    y(0.0) - y(mean)
                );
                let sd = value(r, key, "sd_mm").unwrap_or(0.0);
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
            r#"<text x="{:.1}" y="{:.1}" text-anchor="middle">{r}</text>"#,
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
        let summary = serde_json::json!({
            "tip": {"dgcnn": {"mean_mm": 3.0, "sd_mm": 0.5}, "knn_all": {"mean_mm": 3.5, "sd_mm": 0.2}},
            "middle": {"dgcnn": {"mean_mm": 7.0, "sd_mm": 1.0}, "knn_all": {"mean_mm": 13.5, "sd_mm": 2.0}},
            "base": {"dgcnn": {"mean_mm": null, "sd_mm": null}, "knn_all": {"mean_mm": 20.0, "sd_mm": 1.0}},
        });
        let svg = region_bars(&summary);
        assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
        // Five bars (one value is missing) and a 25 mm axis (21 rounded up to a step of 5).
        assert_eq!(svg.matches("<rect x=").count(), 5 + 2, "{svg}");
        assert!(svg.contains(">25</text>") && !svg.contains(">30</text>"));
    }
}
