//! SVG figures of the demo (plotters, SVG backend only): learning curves, the AUV's x–z
//! trajectories over the current and the target sphere, the hopping leg's apex heights, and
//! several optimizers' cost curves on a log axis ([`log_cost_curves`]).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

/// What a plot function returns.
pub type PlotResult = Result<(), Box<dyn std::error::Error>>;

/// One learning curve: the cost or reward of every episode and the best so far.
pub struct Curve<'a> {
    /// Panel title.
    pub title: &'a str,
    /// The value of every episode, in order.
    pub values: &'a [f64],
    /// The best value after each episode.
    pub best: &'a [f64],
    /// The legend of `best`: what it is (say where it was measured when another figure
    /// re-runs the same θ and reports another value).
    pub best_label: &'a str,
    /// A log-scaled y axis (positive costs spanning decades); non-positive values are left
    /// out.
    pub log_y: bool,
    /// A horizontal reference line (the success threshold), if any.
    pub threshold: Option<(f64, &'a str)>,
}

const BLUE_ISH: RGBColor = RGBColor(31, 119, 180);
const ORANGE: RGBColor = RGBColor(255, 127, 14);
const GREEN: RGBColor = RGBColor(44, 160, 44);
const GREY: RGBColor = RGBColor(120, 120, 120);
const WATER: RGBColor = RGBColor(210, 230, 250);

fn range_of(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo.is_finite() && hi > lo {
        let pad = 0.05 * (hi - lo);
        (lo - pad, hi + pad)
    } else if lo.is_finite() {
        (lo - 1.0, lo + 1.0)
    } else {
        (0.0, 1.0)
    }
}

/// A log axis's range over the positive finite `values`, padded by a factor 1.5.
fn log_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo.is_finite() && hi > lo {
        (lo / 1.5, hi * 1.5)
    } else {
        (1.0, 10.0)
    }
}

fn curve_panel(area: &DrawingArea<SVGBackend, Shift>, curve: &Curve, y_label: &str) -> PlotResult {
    let extra = curve.threshold.map(|(t, _)| t);
    let all = || curve.values.iter().chain(curve.best).copied().chain(extra);
    if curve.log_y {
        let (lo, hi) = log_range(all());
        let mut chart = chart_on(area, curve)
            .build_cartesian_2d(1f64..curve.values.len().max(2) as f64, (lo..hi).log_scale())?;
        chart
            .configure_mesh()
            .x_desc("episode")
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_desc(format!("{y_label} (log scale)"))
            .y_label_formatter(&|y| format!("{y:.0e}"))
            .light_line_style(WHITE)
            .draw()?;
        return draw_curve(&mut chart, curve, |v| v > 0.0);
    }
    let (lo, hi) = range_of(all());
    let mut chart =
        chart_on(area, curve).build_cartesian_2d(1f64..curve.values.len().max(2) as f64, lo..hi)?;
    chart
        .configure_mesh()
        .x_desc("episode")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_desc(y_label)
        .light_line_style(WHITE)
        .draw()?;
    draw_curve(&mut chart, curve, |_| true)
}

fn chart_on<'a, 'b>(
    area: &'a DrawingArea<SVGBackend<'b>, Shift>,
    curve: &Curve,
) -> ChartBuilder<'a, 'b, SVGBackend<'b>> {
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(curve.title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(if curve.log_y { 60 } else { 50 });
    builder
}

/// The episodes (dots), the best so far (a line) and the threshold of `curve`, with the
/// points `keep` accepts (a log axis cannot show values ≤ 0).
fn draw_curve<'a, Y>(
    chart: &mut ChartContext<
        'a,
        SVGBackend<'a>,
        Cartesian2d<plotters::coord::types::RangedCoordf64, Y>,
    >,
    curve: &Curve,
    keep: impl Fn(f64) -> bool,
) -> PlotResult
where
    Y: Ranged<ValueType = f64>,
{
    let n = curve.values.len().max(2) as f64;
    let xs = |v: &[f64]| -> Vec<(f64, f64)> {
        v.iter()
            .enumerate()
            .filter(|(_, y)| keep(**y))
            .map(|(k, y)| ((k + 1) as f64, *y))
            .collect()
    };
    chart
        .draw_series(
            xs(curve.values)
                .into_iter()
                .map(|p| Circle::new(p, 2, BLUE_ISH.mix(0.6).filled())),
        )?
        .label("episode")
        .legend(|(x, y)| Circle::new((x + 10, y), 3, BLUE_ISH.filled()));
    chart
        .draw_series(LineSeries::new(xs(curve.best), ORANGE.stroke_width(2)))?
        .label(curve.best_label)
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], ORANGE.stroke_width(2)));
    if let Some((t, name)) = curve.threshold {
        chart
            .draw_series(LineSeries::new(
                vec![(1.0, t), (n, t)],
                GREY.stroke_width(1),
            ))?
            .label(name)
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], GREY));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(if curve.log_y {
            SeriesLabelPosition::UpperRight
        } else {
            SeriesLabelPosition::LowerRight
        })
        .draw()?;
    Ok(())
}

/// Learning curves side by side, one panel per phase.
pub fn learning_curves(path: &Path, curves: &[Curve], y_label: &str) -> PlotResult {
    let root = SVGBackend::new(path, (520 * curves.len().max(1) as u32, 400)).into_drawing_area();
    root.fill(&WHITE)?;
    let panels = root.split_evenly((1, curves.len().max(1)));
    for (area, curve) in panels.iter().zip(curves) {
        curve_panel(area, curve, y_label)?;
    }
    root.present()?;
    Ok(())
}

/// One series of [`log_cost_curves`].
pub struct Series<'a> {
    /// Legend entry.
    pub name: &'a str,
    /// The value after each rollout (rollout k + 1 at index k), all > 0.
    pub values: &'a [f64],
}

/// Several cost curves against rollouts in one panel, log-scaled y axis (e.g. the mean
/// lowest cost so far of each optimizer).
pub fn log_cost_curves(path: &Path, caption: &str, series: &[Series], y_label: &str) -> PlotResult {
    let n = series
        .iter()
        .map(|s| s.values.len())
        .max()
        .unwrap_or(2)
        .max(2) as f64;
    let (lo, hi) = log_range(series.iter().flat_map(|s| s.values.iter().copied()));
    let root = SVGBackend::new(path, (760, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(70)
        .build_cartesian_2d(1f64..n, (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("rollouts")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_desc(y_label)
        .y_label_formatter(&|y| format!("{y:.1e}"))
        .light_line_style(WHITE)
        .draw()?;
    let colours = [BLUE_ISH, ORANGE, GREEN, GREY, BLACK];
    for (s, colour) in series.iter().zip(colours.iter().cycle()) {
        let points = s
            .values
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite() && **v > 0.0)
            .map(|(k, v)| ((k + 1) as f64, *v));
        let style = colour.stroke_width(2);
        chart
            .draw_series(LineSeries::new(points, style))?
            .label(s.name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()?;
    Ok(())
}

/// An x–z trajectory to draw (metres, z = depth, down).
pub struct Track<'a> {
    /// Legend entry.
    pub name: &'a str,
    /// Positions [x, y, z].
    pub points: &'a [[f64; 3]],
}

/// The AUV's x–z trajectories with the current layer (below `current_depth`, flowing along
/// +x), the sea bed at `seabed`, and the target sphere of radius `radius` (its section in the
/// plane y = 0, where the target lies). Depth increases downwards.
pub fn auv_trajectories(
    path: &Path,
    tracks: &[Track],
    target: [f64; 3],
    radius: f64,
    current_depth: f64,
    seabed: f64,
    caption: &str,
) -> PlotResult {
    let (x0, x1) = (-2.0, 8.0);
    let (z0, z1) = (-0.3, seabed + 0.4);
    // Equal scales on both axes: 80 px per metre.
    let size = (
        ((x1 - x0) * 80.0) as u32 + 70,
        ((z1 - z0) * 80.0) as u32 + 90,
    );
    let root = SVGBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(x0..x1, z1..z0)?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("depth z (m)")
        .light_line_style(WHITE)
        .draw()?;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(x0, current_depth), (x1, seabed)],
            WATER.filled(),
        )))?
        .label("current (+x) below 2 m")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], WATER.filled()));
    chart.draw_series(LineSeries::new(
        vec![(x0, seabed), (x1, seabed)],
        BLACK.stroke_width(2),
    ))?;
    let circle: Vec<(f64, f64)> = (0..=120)
        .map(|k| {
            let a = std::f64::consts::TAU * f64::from(k) / 120.0;
            (target[0] + radius * a.cos(), target[2] + radius * a.sin())
        })
        .collect();
    chart
        .draw_series(LineSeries::new(circle, RED.stroke_width(2)))?
        .label("target, D = 1 m")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
    chart.draw_series(std::iter::once(Cross::new(
        (target[0], target[2]),
        6,
        RED.stroke_width(2),
    )))?;
    let colours = [GREY, BLUE_ISH, GREEN, ORANGE];
    for (track, colour) in tracks.iter().zip(colours.iter().cycle()) {
        let colour = *colour;
        chart
            .draw_series(LineSeries::new(
                track.points.iter().map(|p| (p[0], p[2])),
                colour.stroke_width(2),
            ))?
            .label(track.name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
        if let Some(start) = track.points.first() {
            chart.draw_series(std::iter::once(Circle::new(
                (start[0], start[2]),
                4,
                colour.filled(),
            )))?;
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;
    root.present()?;
    Ok(())
}

/// One hopping episode to draw: apex heights and the ground of the stance before each.
pub struct Hops<'a> {
    /// Legend entry.
    pub name: &'a str,
    /// Apex height of every hop (m).
    pub apexes: &'a [f64],
    /// Ground height under the stance that launched every hop (m).
    pub grounds: &'a [f64],
}

/// Apex heights per hop (cm) of several policies with the set height (top), and the
/// unperceived block under each hop's stance (bottom).
pub fn apex_heights(path: &Path, series: &[Hops], set_height: f64, caption: &str) -> PlotResult {
    let root = SVGBackend::new(path, (720, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let (top, bottom) = root.split_vertically(380);
    let hops = series
        .iter()
        .map(|h| h.apexes.len())
        .max()
        .unwrap_or(1)
        .max(2) as f64;
    let (lo, hi) = range_of(
        series
            .iter()
            .flat_map(|h| h.apexes.iter().map(|v| v * 100.0))
            .chain([set_height * 100.0]),
    );
    let mut chart = ChartBuilder::on(&top)
        .caption(caption, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(20)
        .y_label_area_size(50)
        .build_cartesian_2d(0.5f64..hops + 0.5, lo..hi)?;
    chart
        .configure_mesh()
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_desc("apex height (cm)")
        .light_line_style(WHITE)
        .draw()?;
    chart.draw_series(LineSeries::new(
        vec![(0.5, set_height * 100.0), (hops + 0.5, set_height * 100.0)],
        GREY,
    ))?;
    let colours = [ORANGE, BLUE_ISH, GREEN];
    for (h, colour) in series.iter().zip(colours.iter().cycle()) {
        let colour = *colour;
        let points: Vec<(f64, f64)> = h
            .apexes
            .iter()
            .enumerate()
            .map(|(k, a)| ((k + 1) as f64, a * 100.0))
            .collect();
        chart
            .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))?
            .label(h.name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
        chart.draw_series(
            points
                .into_iter()
                .map(|p| Circle::new(p, 3, colour.filled())),
        )?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;

    let mut ground = ChartBuilder::on(&bottom)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(50)
        .build_cartesian_2d(0.5f64..hops + 0.5, -0.5f64..6.5)?;
    ground
        .configure_mesh()
        .x_desc("hop")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_desc("block (cm)")
        .y_labels(4)
        .light_line_style(WHITE)
        .draw()?;
    let n = series.len().max(1) as f64;
    for (i, (h, colour)) in series.iter().zip(colours.iter().cycle()).enumerate() {
        let width = 0.8 / n;
        let offset = -0.4 + width * i as f64;
        ground.draw_series(h.grounds.iter().enumerate().map(|(k, g)| {
            let x = (k + 1) as f64 + offset;
            Rectangle::new([(x, 0.0), (x + width, g * 100.0)], colour.mix(0.7).filled())
        }))?;
    }
    root.present()?;
    Ok(())
}
