//! `ground archive plot`: HK parameters over time, SVG or PNG (plotters), drawn from the
//! archive's per-pixel-column min/max decimation: one panel per unit, each with its own
//! y axis, and a gap where the data has a hole.

use std::path::Path;

use anyhow::{anyhow, Context, Result};
use ground::archive::{Column, Filter, Store};
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

/// One line of the plot: its legend name, its colour index, and its runs of points
/// (a run ends at a hole in the data, which is drawn as a gap).
struct Series {
    name: String,
    color: usize,
    runs: Vec<Vec<(f64, f64)>>,
}

/// One panel per engineering unit, with its own y axis.
struct Panel {
    unit: &'static str,
    series: Vec<Series>,
}

/// Pixel columns the data is decimated to (the plot is 1000 pixels wide).
pub const COLUMNS: usize = 1000;
/// Height of the title strip and of each panel (pixels).
const TITLE_H: u32 = 40;
const PANEL_H: u32 = 320;

/// A pause between two samples longer than this many typical sample intervals of the
/// series is a hole: the collector's rule for stale housekeeping (its default
/// `stale_hk_intervals`).
fn gap_intervals() -> i64 {
    i64::from(ground::collect::config::Config::default().stale_hk_intervals)
}

/// Splits decimated columns into runs without holes. The typical interval is the median
/// of the sample spacings the columns show (inside a column, and from one column's last
/// sample to the next one's first); a pause longer than [`gap_intervals`] of it ends a run.
fn runs(cols: &[Column]) -> Vec<&[Column]> {
    let mut spacing: Vec<i64> = cols
        .iter()
        .filter(|c| c.n >= 2)
        .map(|c| (c.t_last_ms - c.t_first_ms) / i64::from(c.n - 1))
        .chain(cols.windows(2).map(|w| w[1].t_first_ms - w[0].t_last_ms))
        .collect();
    spacing.sort_unstable();
    let Some(&typical) = spacing.get(spacing.len() / 2) else {
        return vec![cols];
    };
    let limit = typical.max(1) * gap_intervals();
    cols.chunk_by(|a, b| b.t_first_ms - a.t_last_ms <= limit).collect()
}

/// Plots `params` into `out`: one panel per unit, one line per parameter and robot, a
/// gap where the data has a hole. The archive decimates each series to min/max per pixel
/// column ([`Store::decimate`]), so a day of 10 Hz HK draws as fast as a minute. Returns
/// the number of samples plotted.
pub fn plot(store: &mut Store, params: &[String], f: &Filter, out: &Path) -> Result<usize> {
    let mut panels: Vec<Panel> = Vec::new();
    let mut t0 = i64::MAX;
    let mut n = 0usize;
    let mut color = 0;
    let robots = match f.robot {
        Some(r) => vec![r],
        None => store.robots()?,
    };
    for p in params {
        let def = mib::params::by_name(p).ok_or_else(|| anyhow!("unknown HK parameter \"{p}\""))?;
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
            let runs = runs(&cols)
                .into_iter()
                .map(|run| {
                    run.iter()
                        .flat_map(|c| {
                            let x = c.t_ms as f64;
                            [(x, c.first), (x, c.min), (x, c.max), (x, c.last)]
                        })
                        .collect()
                })
                .collect();
            let s = Series {
                name: format!("{} robot {robot}", def.name),
                color,
                runs,
            };
            color += 1;
            match panels.iter_mut().find(|p| p.unit == def.unit) {
                Some(p) => p.series.push(s),
                None => panels.push(Panel {
                    unit: def.unit,
                    series: vec![s],
                }),
            }
        }
    }
    if n == 0 {
        return Err(crate::exit::coded(
            crate::exit::INVALID,
            "no archived values for these parameters",
        ));
    }
    let mut x1 = 0.0f64;
    for p in panels
        .iter_mut()
        .flat_map(|p| p.series.iter_mut())
        .flat_map(|s| s.runs.iter_mut())
    {
        for pt in p {
            pt.0 = (pt.0 - t0 as f64) / 1000.0;
            x1 = x1.max(pt.0);
        }
    }
    let x1 = if x1 <= 0.0 { 1.0 } else { x1 };
    let start = chrono::DateTime::from_timestamp_millis(t0)
        .map_or(String::new(), |t| t.format("%Y-%m-%d %H:%M:%S UTC").to_string());
    let title = format!("{} from {start}", params.join(", ").to_uppercase());
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let text = font();
    let size = (1000, TITLE_H + PANEL_H * panels.len() as u32);
    match ext.as_str() {
        "svg" => {
            let root = SVGBackend::new(out, size).into_drawing_area();
            draw(&root, &panels, x1, &title, text)?;
            root.present().with_context(|| format!("writing {}", out.display()))?;
        }
        "png" => {
            let root = BitMapBackend::new(out, size).into_drawing_area();
            draw(&root, &panels, x1, &title, text)?;
            root.present().with_context(|| format!("writing {}", out.display()))?;
        }
        _ => {
            return Err(crate::exit::coded(
                crate::exit::INVALID,
                "the plot file must end in .svg or .png",
            ))
        }
    }
    Ok(n)
}

/// The y range of a panel's values, padded by 5 %.
fn y_range(p: &Panel) -> (f64, f64) {
    let (mut y0, mut y1) = (f64::MAX, f64::MIN);
    for &(_, y) in p.series.iter().flat_map(|s| s.runs.iter()).flatten() {
        if y.is_finite() {
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
    }
    if y1 < y0 {
        (y0, y1) = (0.0, 0.0);
    }
    if y1 <= y0 {
        y0 -= 1.0;
        y1 += 1.0;
    }
    let pad = (y1 - y0) * 0.05;
    (y0 - pad, y1 + pad)
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    panels: &[Panel],
    x1: f64,
    title: &str,
    text: bool,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("drawing the plot: {e:?}");
    root.fill(&WHITE).map_err(e)?;
    let (top, body) = root.split_vertically(TITLE_H);
    if text {
        top.titled(title, ("sans-serif", 22)).map_err(e)?;
    }
    for (area, panel) in body.split_evenly((panels.len(), 1)).iter().zip(panels) {
        let (y0, y1) = y_range(panel);
        let mut b = ChartBuilder::on(area);
        b.margin(15);
        if text {
            b.x_label_area_size(40).y_label_area_size(60);
        }
        let mut chart = b.build_cartesian_2d(0.0..x1, y0..y1).map_err(e)?;
        let mut mesh = chart.configure_mesh();
        if text {
            let unit = if panel.unit.is_empty() { "(no unit)" } else { panel.unit };
            mesh.x_desc("time since start (s)").y_desc(unit);
        } else {
            mesh.disable_x_axis().disable_y_axis();
        }
        mesh.draw().map_err(e)?;
        for s in &panel.series {
            let color = Palette99::pick(s.color).to_rgba();
            for (i, run) in s.runs.iter().enumerate() {
                let drawn = chart
                    .draw_series(LineSeries::new(
                        run.iter().copied().filter(|p| p.1.is_finite()),
                        color.stroke_width(2),
                    ))
                    .map_err(e)?;
                if text && i == 0 {
                    drawn
                        .label(s.name.clone())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
                }
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
    }
    Ok(())
}
