//! `ground archive plot`: HK parameters over time, SVG or PNG (plotters), drawn from the
//! archive's per-pixel-column min/max decimation.

use std::path::Path;

use anyhow::{anyhow, Context, Result};
use ground::archive::{Filter, Store};
use plotters::prelude::*;

/// Font files tried for labels (plotters' ab_glyph backend needs one registered).
const FONTS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// Registers a system font once; false if none is found (the plot then has no text).
fn font() -> bool {
    static OK: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *OK.get_or_init(|| {
        let from_env = std::env::var("GROUND_FONT").ok();
        for p in from_env.iter().map(String::as_str).chain(FONTS.iter().copied()) {
            if let Ok(bytes) = std::fs::read(p) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                    return true;
                }
            }
        }
        false
    })
}

type Series = (String, Vec<(f64, f64)>);

/// Pixel columns the data is decimated to (the plot is 1000 pixels wide).
pub const COLUMNS: usize = 1000;

/// Plots `params` (one line per parameter and robot) into `out`. The archive decimates
/// each series to min/max per pixel column ([`Store::decimate`]), so a day of 10 Hz HK
/// draws as fast as a minute. Returns the number of samples plotted.
pub fn plot(store: &mut Store, params: &[String], f: &Filter, out: &Path) -> Result<usize> {
    let mut series: Vec<Series> = Vec::new();
    let mut t0 = i64::MAX;
    let mut units = Vec::new();
    let mut n = 0usize;
    let robots = match f.robot {
        Some(r) => vec![r],
        None => store.robots()?,
    };
    for p in params {
        let def = mib::params::by_name(p).ok_or_else(|| anyhow!("unknown HK parameter \"{p}\""))?;
        if !def.unit.is_empty() && !units.contains(&def.unit) {
            units.push(def.unit);
        }
        for &robot in &robots {
            let Some((lo, hi)) = store.param_span(robot, def.id)? else {
                continue;
            };
            let (lo, hi) = (f.since_ms.unwrap_or(lo).max(lo), f.until_ms.unwrap_or(hi).min(hi));
            if hi < lo {
                continue;
            }
            let cols = store.decimate(robot, def.name, lo, hi, COLUMNS)?;
            if cols.is_empty() {
                continue;
            }
            t0 = t0.min(cols[0].t_ms);
            n += cols.iter().map(|c| c.n as usize).sum::<usize>();
            let mut pts = Vec::with_capacity(cols.len() * 4);
            for c in &cols {
                let x = c.t_ms as f64;
                pts.extend([(x, c.first), (x, c.min), (x, c.max), (x, c.last)]);
            }
            series.push((format!("{} robot {robot}", def.name), pts));
        }
    }
    if n == 0 {
        return Err(crate::coded(
            crate::exit::INVALID,
            "no archived values for these parameters",
        ));
    }
    for s in &mut series {
        for p in &mut s.1 {
            p.0 = (p.0 - t0 as f64) / 1000.0;
        }
    }
    let (mut x1, mut y0, mut y1) = (0.0f64, f64::MAX, f64::MIN);
    for (_, pts) in &series {
        for &(x, y) in pts {
            if y.is_finite() {
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
    }
    if y1 <= y0 {
        y0 -= 1.0;
        y1 += 1.0;
    }
    let pad = (y1 - y0) * 0.05;
    let x1 = if x1 <= 0.0 { 1.0 } else { x1 };
    let start = chrono::DateTime::from_timestamp_millis(t0)
        .map_or(String::new(), |t| t.format("%Y-%m-%d %H:%M:%S UTC").to_string());
    let title = format!("{} from {start}", params.join(", ").to_uppercase());
    let ylabel = units.join(", ");
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let text = font();
    match ext.as_str() {
        "svg" => {
            let root = SVGBackend::new(out, (1000, 560)).into_drawing_area();
            draw(&root, &series, (x1, y0 - pad, y1 + pad), &title, &ylabel, text)?;
            root.present().with_context(|| format!("writing {}", out.display()))?;
        }
        "png" => {
            let root = BitMapBackend::new(out, (1000, 560)).into_drawing_area();
            draw(&root, &series, (x1, y0 - pad, y1 + pad), &title, &ylabel, text)?;
            root.present().with_context(|| format!("writing {}", out.display()))?;
        }
        _ => {
            return Err(crate::coded(
                crate::exit::INVALID,
                "the plot file must end in .svg or .png",
            ))
        }
    }
    Ok(n)
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    series: &[Series],
    (x1, y0, y1): (f64, f64, f64),
    title: &str,
    ylabel: &str,
    text: bool,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("drawing the plot: {e:?}");
    root.fill(&WHITE).map_err(e)?;
    let mut b = ChartBuilder::on(root);
    b.margin(15);
    if text {
        b.caption(title, ("sans-serif", 22))
            .x_label_area_size(40)
            .y_label_area_size(60);
    }
    let mut chart = b.build_cartesian_2d(0.0..x1, y0..y1).map_err(e)?;
    let mut mesh = chart.configure_mesh();
    if text {
        mesh.x_desc("time since start (s)").y_desc(ylabel);
    } else {
        mesh.disable_x_axis().disable_y_axis();
    }
    mesh.draw().map_err(e)?;
    for (i, (name, pts)) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let s = chart
            .draw_series(LineSeries::new(
                pts.iter().copied().filter(|p| p.1.is_finite()),
                color.stroke_width(2),
            ))
            .map_err(e)?;
        if text {
            s.label(name.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
        }
    }
    if text {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(e)?;
    }
    Ok(())
}
