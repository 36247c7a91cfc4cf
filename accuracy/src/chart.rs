//! Charts with plotters, as SVG or PNG (chosen by the file extension): speed against accuracy
//! with its Pareto front, scaling over devices with the ideal line, frame time over views,
//! missing pixels against hole-filling time, missing pixels against the reprojection tolerance,
//! and (in
//! [`crate::timeline`]) a per-device timeline of a Chrome trace. 960×600 pixels, 15-18 px text:
//! readable at 100 % zoom. The legend sits beside the plot, never over data, each swatch drawn
//! as its series is (marker, line, dashes or bar); point labels are short (only what tells the
//! points apart), stay inside the plot, and a label that would overlap another label or a
//! marker is left out rather than drawn over it.
//!
//! Every step is linear in the points (a bench's points.json may hold 10⁵ of them): groups and
//! shared words are found through hash maps, and the pixels taken by markers and labels are a
//! bitmap ([`Taken`]), so placing a label costs its own area, not a look at every label placed.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::error::{AccuracyError, Result};
use crate::points::Point;

pub const SIZE: (u32, u32) = (960, 600);
pub(crate) const FONT: &str = "sans-serif";

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Style {
    /// Markers with their labels.
    Points,
    /// A line through the points, with markers.
    Line,
    /// A dashed line without markers (ideal scaling).
    Dashed,
}

#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    /// A measured series and its ideal line share one colour.
    pub color: Colour,
    pub style: Style,
    /// (x, y, label shown next to the marker).
    pub points: Vec<(f64, f64, Option<String>)>,
}

/// A chart of x/y series.
#[derive(Clone, Debug)]
pub struct XyChart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// The x axis counts things (devices, views): ticks between integers stay unlabelled.
    pub integer_x: bool,
}

/// Which accuracy figure the speed-accuracy chart plots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AccuracyAxis {
    Flip,
    Psnr,
}

fn group(points: &[Point], keep: impl Fn(&Point) -> bool) -> Vec<(String, Vec<&Point>)> {
    group_by(points, keep, Point::series_name)
}

/// The points `keep` accepts, grouped by `key` in order of first appearance.
fn group_by<'a, K: AsRef<str>>(
    points: &'a [Point],
    keep: impl Fn(&Point) -> bool,
    key: impl Fn(&'a Point) -> K,
) -> Vec<(String, Vec<&'a Point>)> {
    let mut groups: Vec<(String, Vec<&Point>)> = Vec::new();
    let mut index: HashMap<String, usize> = HashMap::new();
    for p in points.iter().filter(|p| keep(p)) {
        let name = key(p).as_ref().to_string();
        let at = *index.entry(name.clone()).or_insert_with(|| {
            groups.push((name, Vec::new()));
            groups.len() - 1
        });
        groups[at].1.push(p);
    }
    groups
}

/// A tolerance line's name: its case and every other setting a bench cell varies (assignment,
/// sources per set, spp, devices), so that each line changes the tolerance alone; a line through
/// cells that differ in more than the tolerance would zigzag between them.
fn tolerance_line(p: &Point) -> String {
    let mut words = vec![p.case.clone().unwrap_or_else(|| "all".into())];
    words.extend(p.assignment.clone());
    words.extend(p.sources_per_set.map(|k| format!("k{k}")));
    words.extend(p.spp.map(|spp| format!("{spp} spp")));
    words.extend(p.devices.map(|d| format!("{d} dev")));
    words.join(" ")
}

/// The points no other point beats: none has both a lower (or equal) x and a better (or equal)
/// y, where better is lower or, with `higher_y_better`, higher. Sorted by x.
pub fn pareto_front(xy: &[(f64, f64)], higher_y_better: bool) -> Vec<(f64, f64)> {
    let better = |a: f64, b: f64| if higher_y_better { a > b } else { a < b };
    let mut sorted = xy.to_vec();
    // Among equal x, the best y first: it alone can be on the front.
    sorted.sort_by(|a, b| {
        let y = if higher_y_better { b.1.total_cmp(&a.1) } else { a.1.total_cmp(&b.1) };
        a.0.total_cmp(&b.0).then(y)
    });
    let mut front: Vec<(f64, f64)> = Vec::new();
    for p in sorted {
        if front.last().is_none_or(|last| better(p.1, last.1)) {
            front.push(p);
        }
    }
    front
}

fn none_usable(what: &str) -> AccuracyError {
    AccuracyError::Chart(format!("no input point has {what}"))
}

/// Frame time against FLIP or PSNR, one labelled marker per configuration, and the Pareto
/// front over all of them (faster and more accurate dominate) as a dashed line.
pub fn speed_accuracy(points: &[Point], axis: AccuracyAxis) -> Result<XyChart> {
    let y = |p: &Point| match axis {
        AccuracyAxis::Flip => p.flip,
        AccuracyAxis::Psnr => p.psnr.filter(|v| v.is_finite()),
    };
    let groups = group(points, |p| p.frame_ms.is_some() && y(p).is_some());
    if groups.is_empty() {
        return Err(none_usable("both frame_ms and the accuracy figure (compare's JSON of a render folder has)"));
    }
    let all: Vec<(f64, f64)> =
        groups.iter().flat_map(|(_, ps)| ps.iter().filter_map(|p| Some((p.frame_ms?, y(p)?)))).collect();
    let front_xy = pareto_front(&all, axis == AccuracyAxis::Psnr);
    let front = Series {
        name: "Pareto front".into(),
        color: Colour::Neutral,
        style: Style::Dashed,
        points: front_xy.iter().map(|&(x, y)| (x, y, None)).collect(),
    };
    let names = short_labels(&groups.iter().flat_map(|(_, ps)| ps.iter().map(|p| p.label.clone())).collect::<Vec<_>>());
    let mut names = names.into_iter();
    // Every point is numbered (the legend's key names it), so points off the front can be told
    // apart too; a number with no free place is left out, and the key says so.
    let mut series: Vec<Series> = groups
        .into_iter()
        .enumerate()
        .map(|(color, (name, ps))| Series {
            name,
            color: Colour::Palette(color),
            style: Style::Points,
            points: ps
                .iter()
                .map(|p| (p, names.next()))
                .filter_map(|(p, label)| {
                    let (x, y) = (p.frame_ms?, y(p)?);
                    Some((x, y, label))
                })
                .collect(),
        })
        .collect();
    // First, so that the markers are drawn over it.
    series.insert(0, front);
    Ok(XyChart {
        title: "Speed against accuracy (dashed: the Pareto front)".into(),
        x_label: "frame time (ms)".into(),
        y_label: match axis {
            AccuracyAxis::Flip => "mean FLIP (LDR, lower is better)".into(),
            AccuracyAxis::Psnr => "PSNR, linear clamped (dB, higher is better)".into(),
        },
        series,
        integer_x: false,
    })
}

/// Frame time against device count per series, each with its ideal line t(d₀)·d₀/d from the
/// series' smallest device count d₀.
pub fn scaling(points: &[Point]) -> Result<XyChart> {
    let groups = group(points, |p| p.frame_ms.is_some() && p.devices.is_some());
    if groups.is_empty() {
        return Err(none_usable("both frame_ms and devices"));
    }
    let mut series = Vec::new();
    for (color, (name, mut ps)) in groups.into_iter().enumerate() {
        ps.sort_by_key(|p| p.devices);
        let xy: Vec<(f64, f64, Option<String>)> =
            ps.iter().map(|p| (p.devices.unwrap() as f64, p.frame_ms.unwrap(), None)).collect();
        let (d0, t0) = (xy[0].0, xy[0].1);
        let ideal = xy.iter().map(|&(d, _, _)| (d, t0 * d0 / d, None)).collect();
        let label = if name.is_empty() { String::new() } else { format!("{name}, ") };
        series.push(Series {
            name: format!("{label}measured"),
            color: Colour::Palette(color),
            style: Style::Line,
            points: xy,
        });
        series.push(Series {
            name: format!("{label}ideal"),
            color: Colour::Palette(color),
            style: Style::Dashed,
            points: ideal,
        });
    }
    Ok(XyChart {
        title: "Scaling over devices".into(),
        x_label: "devices".into(),
        y_label: "frame time (ms)".into(),
        series,
        integer_x: true,
    })
}

/// Frame time against the number of views, one line per series.
pub fn frame_time_over_views(points: &[Point]) -> Result<XyChart> {
    let groups = group(points, |p| p.frame_ms.is_some() && p.views.is_some());
    if groups.is_empty() {
        return Err(none_usable("both frame_ms and views"));
    }
    let series = groups
        .into_iter()
        .enumerate()
        .map(|(color, (name, mut ps))| {
            ps.sort_by_key(|p| p.views);
            let points = ps.iter().map(|p| (p.views.unwrap() as f64, p.frame_ms.unwrap(), None)).collect();
            let name = if name.is_empty() { "frame time".into() } else { name };
            Series { name, color: Colour::Palette(color), style: Style::Line, points }
        })
        .collect();
    Ok(XyChart {
        title: "Frame time over the number of views".into(),
        x_label: "views".into(),
        y_label: "frame time (ms)".into(),
        series,
        integer_x: true,
    })
}

/// Missing pixels (%) against hole-filling time per frame, one series per assignment, one
/// point per configuration that has both, labelled by sources per set and spp ("k2 spp4").
pub fn holes(points: &[Point]) -> Result<XyChart> {
    let groups = group_by(
        points,
        |p| p.missing.is_some() && p.hole_fill_ms.is_some(),
        |p| p.assignment.as_deref().unwrap_or("assignment not given"),
    );
    if groups.is_empty() {
        return Err(none_usable("both missing and hole_fill_ms (bench's points.json has them for reprojecting cells)"));
    }
    // What tells the points apart (their ids less what all share), so no two read the same.
    let mut names =
        short_labels(&groups.iter().flat_map(|(_, ps)| ps.iter().map(|p| p.label.clone())).collect::<Vec<_>>())
            .into_iter();
    let series = groups
        .into_iter()
        .enumerate()
        .map(|(color, (name, ps))| Series {
            name,
            color: Colour::Palette(color),
            style: Style::Points,
            points: ps
                .iter()
                .map(|p| (p, names.next()))
                .filter_map(|(p, label)| Some((100.0 * p.missing?, p.hole_fill_ms?, label)))
                .collect(),
        })
        .collect();
    Ok(XyChart {
        title: "Missing pixels against hole-filling time".into(),
        x_label: "missing pixels (%)".into(),
        y_label: "hole filling (ms per frame, all devices)".into(),
        series,
        integer_x: false,
    })
}

/// Labels shortened to what tells them apart: a `case/` prefix all share is dropped, and so is
/// every `_`-separated word all of them have (`reproject_multi-source_k1_spp4_dnon_d1` among
/// cells that differ only in pipeline and spp reads `reproject spp4`). Labels that would read
/// alike keep their words.
pub fn short_labels(labels: &[String]) -> Vec<String> {
    let prefix = labels.first().and_then(|l| l.split_once('/')).map(|(p, _)| format!("{p}/"));
    let prefix = prefix.filter(|p| labels.iter().all(|l| l.starts_with(p.as_str()))).unwrap_or_default();
    let words: Vec<Vec<&str>> =
        labels.iter().map(|l| l[prefix.len()..].split(['_', ' ']).filter(|w| !w.is_empty()).collect()).collect();
    // How many labels have each word (once per label): a word all of them have is shared.
    let mut having: HashMap<&str, usize> = HashMap::new();
    for ws in &words {
        for w in ws.iter().copied().collect::<HashSet<&str>>() {
            *having.entry(w).or_default() += 1;
        }
    }
    let shared = |w: &str| having.get(w) == Some(&words.len());
    let short: Vec<String> = words
        .iter()
        .map(|ws| {
            let kept: Vec<&str> = ws.iter().copied().filter(|w| !shared(w)).collect();
            if kept.is_empty() { ws.join(" ") } else { kept.join(" ") }
        })
        .collect();
    let mut readings: HashMap<&str, usize> = HashMap::new();
    for s in &short {
        *readings.entry(s).or_default() += 1;
    }
    short.iter().zip(&words).map(|(s, ws)| if readings[s.as_str()] > 1 { ws.join(" ") } else { s.clone() }).collect()
}

/// Missing pixels (%) against the reprojection tolerance, one line per bench case (points of
/// reprojecting cells), each point labelled with its accuracy figure of `accuracy` when it has
/// one: where reprojecting more starts to cost accuracy.
pub fn tolerance(points: &[Point], accuracy: AccuracyAxis) -> Result<XyChart> {
    let groups = group_by(points, |p| p.missing.is_some() && p.reprojection_tolerance.is_some(), tolerance_line);
    if groups.is_empty() {
        return Err(none_usable(
            "both missing and reprojection_tolerance (bench's points.json has them for reprojecting cells)",
        ));
    }
    let label = |p: &Point| match accuracy {
        AccuracyAxis::Flip => p.flip.map(|f| format!("FLIP {f:.4}")),
        AccuracyAxis::Psnr => p.psnr.map(|db| format!("{db:.2} dB")),
    };
    let series = groups
        .into_iter()
        .enumerate()
        .map(|(color, (name, ps))| {
            let mut points: Vec<(f64, f64, Option<String>)> =
                ps.iter().filter_map(|p| Some((p.reprojection_tolerance?, 100.0 * p.missing?, label(p)))).collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            Series { name, color: Colour::Palette(color), style: Style::Line, points }
        })
        .collect();
    Ok(XyChart {
        title: "Missing pixels against the reprojection tolerance".into(),
        x_label: "reprojection tolerance (bound on the relative error from view-dependence)".into(),
        y_label: "missing pixels (%)".into(),
        series,
        integer_x: false,
    })
}

/// At most this many ticks on an x axis: about 100 px each across the plot, room for an
/// 8-character label at 15 px.
pub(crate) const X_TICKS: usize = 6;
/// At most this many ticks on a y axis (60 px each).
const Y_TICKS: usize = 8;

/// A tick's label: `v` at the precision an axis spanning `span` needs (a hundredth of the span;
/// the ticks are round numbers at least a tenth apart), trailing zeros dropped, so that a tick at
/// 0.1 + 0.2 reads `0.3`, not `0.30000000000000004`, and 1000 reads `1000`, not `1000.0`.
pub(crate) fn tick_label(v: f64, span: f64) -> String {
    let step = span / 100.0;
    let decimals = if step.is_finite() && step > 0.0 { (-step.log10().floor()).clamp(0.0, 12.0) as usize } else { 0 };
    let text = format!("{v:.decimals$}");
    let text = if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.') } else { &text };
    if text == "-0" { "0".into() } else { text.to_string() }
}

pub(crate) fn chart_err(e: impl std::fmt::Display) -> AccuracyError {
    AccuracyError::Chart(e.to_string())
}

/// Padded range covering `values` (never empty, starts at 0 when all values are positive and
/// 0 is near).
fn range(values: impl Iterator<Item = f64>, from_zero: bool) -> std::ops::Range<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    let lo = if from_zero && lo >= 0.0 { 0.0 } else { lo };
    let pad = ((hi - lo) * 0.08).max(hi.abs() * 0.05).max(1e-9);
    (lo - if from_zero && lo == 0.0 { 0.0 } else { pad })..(hi + pad)
}

/// The colour of a series.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Colour {
    /// Entry `i` of the palette.
    Palette(usize),
    /// Dark grey: lines of no one series (the Pareto front), which a palette colour would tie
    /// to a series or draw too faintly.
    Neutral,
}

impl Colour {
    pub(crate) fn rgb(self) -> RGBColor {
        match self {
            Colour::Palette(i) => color(i),
            Colour::Neutral => RGBColor(70, 70, 70),
        }
    }
}

pub(crate) fn color(i: usize) -> RGBColor {
    let c = Palette99::pick(i).to_rgba();
    RGBColor(c.0, c.1, c.2)
}

/// Width of the legend beside the plot, in pixels.
pub(crate) const LEGEND_WIDTH: u32 = 240;

/// How a legend entry's swatch is drawn: as its series is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Swatch {
    Marker,
    LineWithMarker,
    Dashed,
    Bar,
}

/// The legend in its own area beside the plot: one entry per series, its swatch, then its name
/// wrapped to the area's width; then the key of the numbered points. What would start below
/// the area is not drawn (the file would carry it unseen).
pub(crate) fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(String, RGBColor, Swatch)],
    key: &[(usize, String)],
) -> Result<()> {
    let font = (FONT, 15).into_font();
    let chars_per_line = ((LEGEND_WIDTH as i32 - 50) / 8).max(8) as usize;
    let bottom = area.dim_in_pixel().1 as i32;
    let mut y = 70;
    for (name, c, swatch) in entries {
        if y > bottom {
            break;
        }
        let (x0, x1) = (8, 36);
        match swatch {
            Swatch::Marker => area.draw(&Circle::new((22, y), 5, c.filled())),
            Swatch::LineWithMarker => area
                .draw(&PathElement::new(vec![(x0, y), (x1, y)], c.stroke_width(2)))
                .and_then(|_| area.draw(&Circle::new((22, y), 4, c.filled()))),
            Swatch::Dashed => (0..3).try_for_each(|k| {
                let a = x0 + k * 11;
                area.draw(&PathElement::new(vec![(a, y), (a + 6, y)], c.stroke_width(2)))
            }),
            Swatch::Bar => area.draw(&Rectangle::new([(x0 + 4, y - 6), (x1 - 4, y + 6)], c.mix(0.8).filled())),
        }
        .map_err(chart_err)?;
        for line in wrap(name, chars_per_line) {
            area.draw(&Text::new(line, (44, y - 8), font.clone())).map_err(chart_err)?;
            y += 19;
        }
        y += 6;
    }
    y += 10;
    let small = (FONT, 14).into_font();
    for (n, label) in key {
        if y > bottom {
            break;
        }
        area.draw(&Text::new(n.to_string(), (14, y - 8), small.clone())).map_err(chart_err)?;
        for line in wrap(label, chars_per_line) {
            area.draw(&Text::new(line, (44, y - 8), small.clone())).map_err(chart_err)?;
            y += 17;
        }
    }
    Ok(())
}

/// `text` in lines of at most `width` characters, broken at spaces where it can be.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for word in text.split(' ') {
        match lines.last_mut() {
            Some(line) if line.chars().count() + 1 + word.chars().count() <= width => {
                line.push(' ');
                line.push_str(word);
            }
            _ => lines.push(word.to_string()),
        }
    }
    lines
}

/// A pixel box `(x0, y0, x1, y1)`, x1 and y1 excluded.
type PixelBox = (i32, i32, i32, i32);

/// The pixels of a plot area that markers and labels cover, one bit each: two boxes overlap
/// exactly when they share a pixel, so asking whether a box is free costs its rows times its
/// width / 64 words, however many boxes are taken.
struct Taken {
    bounds: PixelBox,
    words_per_row: usize,
    bits: Vec<u64>,
}

impl Taken {
    fn new(bounds: PixelBox) -> Self {
        let (width, height) = ((bounds.2 - bounds.0).max(0) as usize, (bounds.3 - bounds.1).max(0) as usize);
        let words_per_row = width.div_ceil(64);
        Self { bounds, words_per_row, bits: vec![0; words_per_row * height] }
    }

    /// `b` clipped to the area, as (columns, rows) relative to it; `None` when nothing is left.
    fn clip(&self, b: PixelBox) -> Option<(std::ops::Range<usize>, std::ops::Range<usize>)> {
        let (x0, y0) = (b.0.max(self.bounds.0) - self.bounds.0, b.1.max(self.bounds.1) - self.bounds.1);
        let (x1, y1) = (b.2.min(self.bounds.2) - self.bounds.0, b.3.min(self.bounds.3) - self.bounds.1);
        (x0 < x1 && y0 < y1).then_some((x0 as usize..x1 as usize, y0 as usize..y1 as usize))
    }

    /// The words of row `y` that hold columns `columns`, each with the mask of those columns.
    fn row_words(
        words_per_row: usize,
        y: usize,
        columns: &std::ops::Range<usize>,
    ) -> impl Iterator<Item = (usize, u64)> {
        let (first, last) = (columns.start / 64, (columns.end - 1) / 64);
        let (start, end, row) = (columns.start, columns.end, y * words_per_row);
        (first..=last).map(move |w| {
            let lo = start.max(w * 64) - w * 64;
            let hi = end.min(w * 64 + 64) - w * 64;
            let mask = if hi - lo == 64 { u64::MAX } else { ((1u64 << (hi - lo)) - 1) << lo };
            (row + w, mask)
        })
    }

    /// Takes the pixels of `b` that lie in the area.
    fn mark(&mut self, b: PixelBox) {
        let Some((columns, rows)) = self.clip(b) else { return };
        for y in rows {
            for (word, mask) in Self::row_words(self.words_per_row, y, &columns) {
                self.bits[word] |= mask;
            }
        }
    }

    /// No pixel of `b` is taken.
    fn is_free(&self, b: PixelBox) -> bool {
        let Some((columns, rows)) = self.clip(b) else { return true };
        rows.into_iter()
            .all(|y| Self::row_words(self.words_per_row, y, &columns).all(|(w, mask)| self.bits[w] & mask == 0))
    }
}

/// Where a `w`×`h` label of a marker at pixel `(px, py)` goes: the first of eight places around
/// it, near ones first, inside `bounds` that covers nothing `taken`; `None` when every place
/// does.
fn label_place((px, py): (i32, i32), (w, h): (i32, i32), bounds: PixelBox, taken: &Taken) -> Option<(i32, i32)> {
    let near = [(7, -h - 1), (7, 1), (-w - 7, -h - 1), (-w - 7, 1)];
    let far = [(-w / 2, -h - 8), (-w / 2, 8), (16, -h / 2), (-w - 16, -h / 2)];
    near.into_iter().chain(far).find(|&(dx, dy)| {
        let b = (px + dx, py + dy, px + dx + w, py + dy + h);
        b.0 >= bounds.0 && b.1 >= bounds.1 && b.2 <= bounds.2 && b.3 <= bounds.3 && taken.is_free(b)
    })
}

impl XyChart {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()> {
        root.fill(&WHITE).map_err(chart_err)?;
        let (plot, legend) = root.split_horizontally(SIZE.0 - LEGEND_WIDTH);
        let all = || self.series.iter().flat_map(|s| s.points.iter());
        let xr = range(all().map(|p| p.0), true);
        let yr = range(all().map(|p| p.1), true);
        let (x_span, y_span) = (xr.end - xr.start, yr.end - yr.start);
        let integer_x = self.integer_x;
        let mut chart = ChartBuilder::on(&plot)
            .caption(&self.title, (FONT, 20))
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(xr, yr)
            .map_err(chart_err)?;
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 17))
            .x_labels(X_TICKS)
            .y_labels(Y_TICKS)
            .x_label_formatter(&|x: &f64| {
                if !integer_x {
                    tick_label(*x, x_span)
                } else if (x - x.round()).abs() < 1e-6 {
                    format!("{}", x.round())
                } else {
                    String::new()
                }
            })
            .y_label_formatter(&|y: &f64| tick_label(*y, y_span))
            .draw()
            .map_err(chart_err)?;
        let (xs, ys) = chart.plotting_area().get_pixel_range();
        let bounds = (xs.start, ys.start, xs.end, ys.end);
        // Every marker's box is taken before any label is placed, so no label covers a marker.
        let mut taken = Taken::new(bounds);
        for p in all() {
            let (x, y) = chart.backend_coord(&(p.0, p.1));
            taken.mark((x - 5, y - 5, x + 5, y + 5));
        }
        let mut entries = Vec::new();
        let mut key: Vec<(usize, String)> = Vec::new();
        for s in &self.series {
            let c = s.color.rgb();
            let xy: Vec<(f64, f64)> = s.points.iter().map(|p| (p.0, p.1)).collect();
            let swatch = match s.style {
                Style::Points => {
                    chart.draw_series(xy.iter().map(|&p| Circle::new(p, 5, c.filled()))).map_err(chart_err)?;
                    Swatch::Marker
                }
                // A line through points of one x would be a vertical stroke, read as a
                // measured trend: such a series is its points.
                Style::Line if xy.iter().any(|p| p.0 != xy[0].0) => {
                    chart.draw_series(xy.iter().map(|&p| Circle::new(p, 4, c.filled()))).map_err(chart_err)?;
                    chart.draw_series(LineSeries::new(xy.clone(), c.stroke_width(2))).map_err(chart_err)?;
                    Swatch::LineWithMarker
                }
                Style::Line => {
                    chart.draw_series(xy.iter().map(|&p| Circle::new(p, 5, c.filled()))).map_err(chart_err)?;
                    Swatch::Marker
                }
                Style::Dashed => {
                    chart.draw_series(DashedLineSeries::new(xy.clone(), 8, 6, c.stroke_width(2))).map_err(chart_err)?;
                    Swatch::Dashed
                }
            };
            entries.push((if s.name.is_empty() { "points".to_string() } else { s.name.clone() }, c, swatch));
            // A labelled point shows a number beside its marker; the legend's key says what it is.
            let mut numbers = Vec::new();
            for (x, y, label) in &s.points {
                let Some(label) = label else { continue };
                let n = key.len() + 1;
                let pixel = chart.backend_coord(&(*x, *y));
                let size = (n.to_string().len() as i32 * 8 + 2, 15);
                let Some((dx, dy)) = label_place(pixel, size, bounds, &taken) else {
                    key.push((n, format!("{label} (not shown: no room)")));
                    continue;
                };
                taken.mark((pixel.0 + dx, pixel.1 + dy, pixel.0 + dx + size.0, pixel.1 + dy + size.1));
                key.push((n, label.clone()));
                numbers.push(EmptyElement::at((*x, *y)) + Text::new(n.to_string(), (dx + 1, dy), (FONT, 14)));
            }
            chart.draw_series(numbers).map_err(chart_err)?;
        }
        draw_legend(&legend, &entries, &key)?;
        root.present().map_err(chart_err)
    }

    /// Writes the chart to `path`: SVG or PNG by its extension.
    pub fn write(&self, path: &Path) -> Result<()> {
        write_chart(path, |root| self.draw(root), |root| self.draw(root))
    }
}

/// Renders with `svg` or `png` (the same drawing on either backend) and writes `path`
/// atomically.
pub(crate) fn write_chart(
    path: &Path,
    svg: impl FnOnce(&DrawingArea<SVGBackend<'_>, Shift>) -> Result<()>,
    png: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<()>,
) -> Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let bytes = match ext.as_deref() {
        Some("svg") => {
            let mut text = String::new();
            svg(&SVGBackend::with_string(&mut text, SIZE).into_drawing_area())?;
            text.into_bytes()
        }
        Some("png") => {
            let mut rgb = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
            png(&BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area())?;
            let mut out = Vec::new();
            let img = image::RgbImage::from_raw(SIZE.0, SIZE.1, rgb).expect("buffer of the chart size");
            img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png).map_err(chart_err)?;
            out
        }
        _ => {
            return Err(AccuracyError::BadInput {
                path: path.into(),
                detail: "a chart file must end in .svg or .png".into(),
            });
        }
    };
    crate::accumulate::write_atomically(path, |f| std::io::Write::write_all(f, &bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(assignment: &str, k: u32, missing: Option<f64>, hole_fill_ms: Option<f64>) -> Point {
        Point {
            label: format!("{assignment} k{k}"),
            assignment: Some(assignment.into()),
            sources_per_set: Some(k),
            spp: Some(1),
            missing,
            hole_fill_ms,
            ..Default::default()
        }
    }

    #[test]
    fn tolerance_has_a_line_per_case_sorted_by_tolerance_and_labelled_with_accuracy() {
        let point = |case: &str, t: f64, missing: f64, psnr: Option<f64>| Point {
            label: format!("{case}/{t}"),
            case: Some(case.into()),
            missing: Some(missing),
            reprojection_tolerance: Some(t),
            psnr,
            ..Default::default()
        };
        let points = [
            point("sponza", 0.5, 0.02, Some(37.7)),
            point("sponza", 0.05, 0.06, Some(37.8)),
            point("default", 0.2, 0.04, None),
            Point { reprojection_tolerance: None, ..point("sponza", 1.0, 0.01, None) },
        ];
        let chart = tolerance(&points, AccuracyAxis::Psnr).unwrap();
        let names: Vec<&str> = chart.series.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["sponza", "default"]);
        assert_eq!(chart.series[0].points, [(0.05, 6.0, Some("37.80 dB".into())), (0.5, 2.0, Some("37.70 dB".into()))]);
        assert_eq!(chart.series[1].points, [(0.2, 4.0, None)]);
        assert!(
            tolerance(&points[3..], AccuracyAxis::Flip).unwrap_err().to_string().contains("reprojection_tolerance")
        );
        // Cells of one case that differ in more than the tolerance are lines of their own.
        let cell = |assignment: &str, t: f64| Point {
            assignment: Some(assignment.into()),
            sources_per_set: Some(2),
            spp: Some(1),
            ..point("cornell", t, 0.05, None)
        };
        let cells = [cell("compact", 0.2), cell("round-robin", 0.2), cell("compact", 1.0), cell("round-robin", 1.0)];
        let chart = tolerance(&cells, AccuracyAxis::Psnr).unwrap();
        let lines: Vec<(&str, Vec<f64>)> =
            chart.series.iter().map(|s| (s.name.as_str(), s.points.iter().map(|p| p.0).collect())).collect();
        assert_eq!(
            lines,
            [("cornell compact k2 1 spp", vec![0.2, 1.0]), ("cornell round-robin k2 1 spp", vec![0.2, 1.0])]
        );
    }

    #[test]
    fn holes_has_a_series_per_assignment_of_the_points_with_both_figures() {
        let points = [
            cell("compact", 1, Some(0.02), Some(0.5)),
            cell("compact", 2, Some(0.01), Some(0.4)),
            cell("round-robin", 1, Some(0.05), Some(0.9)),
            cell("contiguous", 1, Some(0.03), None),
        ];
        let chart = holes(&points).unwrap();
        let names: Vec<&str> = chart.series.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["compact", "round-robin"]);
        assert_eq!(chart.series[0].points[1], (1.0, 0.4, Some("compact k2".into())));
        let none = [cell("compact", 1, Some(0.02), None), cell("compact", 1, None, Some(0.5))];
        assert!(holes(&none).unwrap_err().to_string().contains("both missing and hole_fill_ms"));
    }

    #[test]
    fn short_labels_keep_what_tells_points_apart() {
        let ids = [
            "sponza/reproject_multi-source_k1_spp1_dnon_d1",
            "sponza/reproject_multi-source_k1_spp4_dnon_d1",
            "sponza/path-trace_multi-source_k1_spp1_dnon_d1",
        ]
        .map(String::from);
        assert_eq!(short_labels(&ids), ["reproject spp1", "reproject spp4", "path-trace spp1"]);
        // Two that differ only in a word they both have elsewhere keep every word.
        let alike = ["a_x_y", "a_y_x"].map(String::from);
        assert_eq!(short_labels(&alike), ["a x y", "a y x"]);
        assert_eq!(short_labels(&["one_label".to_string()]), ["one label"]);
    }

    /// `bounds` with `boxes` taken.
    fn taken(bounds: PixelBox, boxes: &[PixelBox]) -> Taken {
        let mut t = Taken::new(bounds);
        boxes.iter().for_each(|&b| t.mark(b));
        t
    }

    #[test]
    fn labels_go_where_nothing_else_is_or_nowhere() {
        let bounds = (0, 0, 200, 100);
        let none = taken(bounds, &[]);
        assert_eq!(label_place((50, 50), (40, 16), bounds, &none), Some((7, -17)), "above right first");
        assert_eq!(label_place((50, 50), (40, 16), bounds, &taken(bounds, &[(57, 33, 97, 49)])), Some((7, 1)));
        assert_eq!(label_place((190, 50), (40, 16), bounds, &none), Some((-47, -17)), "not past the right edge");
        let full = taken(bounds, &[(0, 0, 200, 100)]);
        assert_eq!(label_place((50, 50), (40, 16), bounds, &full), None, "left out, not overlapped");
    }

    /// The bitmap says a box is free exactly when it overlaps none of the boxes taken (as
    /// intervals: sharing an edge is no overlap), across word boundaries and the area's edges.
    #[test]
    fn taken_pixels_agree_with_box_overlap() {
        let overlaps = |a: PixelBox, b: PixelBox| a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3;
        let bounds = (3, 2, 203, 62);
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut next = |n: i32| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % n as u64) as i32
        };
        let mut random_box = || {
            let (x, y) = (next(220) - 10, next(80) - 10);
            // Never empty, as markers and labels are not.
            (x, y, x + 1 + next(70), y + 1 + next(20))
        };
        let boxes: Vec<PixelBox> = (0..40).map(|_| random_box()).collect();
        let t = taken(bounds, &boxes);
        for _ in 0..4000 {
            let b = random_box();
            let inside = (b.0.max(bounds.0), b.1.max(bounds.1), b.2.min(bounds.2), b.3.min(bounds.3));
            let empty = inside.0 >= inside.2 || inside.1 >= inside.3;
            assert_eq!(t.is_free(b), empty || !boxes.iter().any(|&o| overlaps(inside, o)), "{b:?}");
        }
    }

    #[test]
    fn speed_accuracy_labels_every_point() {
        let p = |label: &str, frame_ms: f64, flip: f64| Point {
            label: label.into(),
            frame_ms: Some(frame_ms),
            flip: Some(flip),
            ..Default::default()
        };
        let chart = speed_accuracy(
            &[p("a_fast", 10.0, 0.05), p("a_slow", 20.0, 0.08), p("a_good", 30.0, 0.01)],
            AccuracyAxis::Flip,
        )
        .unwrap();
        let labels: Vec<Option<String>> = chart.series[1].points.iter().map(|p| p.2.clone()).collect();
        assert_eq!(labels, [Some("fast".into()), Some("slow".into()), Some("good".into())]);
    }

    #[test]
    fn ticks_read_as_round_numbers() {
        assert_eq!(tick_label(0.1 + 0.2, 1.05), "0.3");
        assert_eq!(tick_label(0.05, 0.5), "0.05");
        assert_eq!(tick_label(1000.0, 1500.0), "1000");
        assert_eq!(tick_label(1500.000000001, 1500.0), "1500");
        assert_eq!(tick_label(-1e-17, 1.0), "0");
        assert_eq!(tick_label(2.5, 10.0), "2.5");
        assert_eq!(tick_label(0.7000000000000001, 0.8), "0.7");
    }

    #[test]
    fn the_pareto_front_keeps_the_undominated_points() {
        let xy = [(10.0, 0.05), (20.0, 0.03), (15.0, 0.06), (30.0, 0.03), (10.0, 0.04), (40.0, 0.01)];
        assert_eq!(pareto_front(&xy, false), [(10.0, 0.04), (20.0, 0.03), (40.0, 0.01)]);
        assert_eq!(pareto_front(&[(10.0, 30.0), (20.0, 29.0), (25.0, 35.0)], true), [(10.0, 30.0), (25.0, 35.0)]);
    }
}
