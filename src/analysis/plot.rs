//! PNG line charts of simulation against reference (plotters on an RGB buffer, saved with `image`).

use plotters::prelude::*;
use std::path::Path;

static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSansMono.ttf");
static FONT_ONCE: std::sync::Once = std::sync::Once::new();

/// One curve: label, points, drawn as a line (`markers = false`) or as markers.
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub markers: bool,
}

pub struct Chart<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub series: Vec<Series>,
}

const COLOURS: [RGBColor; 8] = [
    RGBColor(200, 30, 30),
    RGBColor(20, 20, 20),
    RGBColor(30, 90, 200),
    RGBColor(30, 150, 60),
    RGBColor(200, 120, 0),
    RGBColor(130, 40, 160),
    RGBColor(0, 150, 160),
    RGBColor(120, 120, 120),
];

/// Renders a chart to a PNG file.
pub fn line_chart(path: &Path, chart: &Chart) -> Result<(), String> {
    FONT_ONCE.call_once(|| {
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
    let (w, h) = (900u32, 600u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let pts = chart.series.iter().flat_map(|s| s.points.iter()).filter(|p| p.0.is_finite() && p.1.is_finite());
        let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for &(x, y) in pts {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        if !(x0.is_finite() && y0.is_finite()) {
            return Err("no finite points to plot".into());
        }
        if x1 - x0 < 1e-30 {
            x1 = x0 + 1.0;
        }
        let pad = 0.05 * (y1 - y0).max(1e-30);
        let (y0, y1) = (y0 - pad, y1 + pad);
        let mut cc = ChartBuilder::on(&root)
            .caption(chart.title, ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(80)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        cc.configure_mesh()
            .x_desc(chart.x_label)
            .y_desc(chart.y_label)
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(|e| e.to_string())?;
        for (k, s) in chart.series.iter().enumerate() {
            let col = COLOURS[k % COLOURS.len()];
            let pts: Vec<(f64, f64)> =
                s.points.iter().copied().filter(|p| p.0.is_finite() && p.1.is_finite()).collect();
            if s.markers {
                cc.draw_series(pts.iter().map(|&p| Circle::new(p, 3, col.filled())))
                    .map_err(|e| e.to_string())?
                    .label(s.label.clone())
                    .legend(move |(x, y)| Circle::new((x + 10, y), 3, col.filled()));
            } else {
                cc.draw_series(LineSeries::new(pts, col.stroke_width(2)))
                    .map_err(|e| e.to_string())?
                    .label(s.label.clone())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
            }
        }
        cc.configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    image::save_buffer(path, &buf, w, h, image::ColorType::Rgb8).map_err(|e| format!("{}: {e}", path.display()))
}
