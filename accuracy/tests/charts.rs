//! Every chart kind is written as SVG and PNG; the SVG parses as XML and names the expected
//! series (legend) and point labels, its tick labels are round numbers that do not overlap, and
//! the PNG decodes at the chart size.

use std::path::Path;

use parallax_accuracy::Point;
use parallax_accuracy::chart::{self, AccuracyAxis, SIZE};
use parallax_accuracy::points::{load_points, of_case};
use parallax_accuracy::timeline::Timeline;

fn point(label: &str, series: &str, frame_ms: f64, flip: f64, devices: u32, views: u32) -> Point {
    Point {
        label: label.into(),
        series: Some(series.into()),
        frame_ms: Some(frame_ms),
        flip: Some(flip),
        psnr: Some(30.0 - 100.0 * flip),
        devices: Some(devices),
        views: Some(views),
        ..Default::default()
    }
}

fn points() -> Vec<Point> {
    vec![
        point("multi-source 1 GPU", "multi-source", 40.0, 0.05, 1, 8),
        point("multi-source 2 GPUs", "multi-source", 22.0, 0.05, 2, 16),
        point("fine-all 1 GPU", "fine-all", 41.0, 0.04, 1, 8),
        point("fine-all 2 GPUs", "fine-all", 30.0, 0.04, 2, 16),
    ]
}

/// All text in an SVG (plotters writes labels as <text> elements).
fn svg_texts(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap_or_else(|e| panic!("{}: not XML: {e}", path.display()));
    assert_eq!(doc.root_element().tag_name().name(), "svg");
    doc.descendants()
        .filter(|n| n.has_tag_name("text"))
        .filter_map(|n| n.text().map(|t| t.trim().to_string()))
        .collect()
}

/// A numeric tick label of an SVG: its text and its box (x0, y0, x1, y1) in pixels, from its
/// anchor and font size (a character is at most 0.6 em wide).
fn tick_boxes(path: &Path) -> Vec<(String, (f64, f64, f64, f64))> {
    let text = std::fs::read_to_string(path).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    doc.descendants()
        .filter(|n| n.has_tag_name("text"))
        .filter_map(|n| {
            let t = n.text()?.trim().to_string();
            t.parse::<f64>().ok()?;
            let num = |a: &str| n.attribute(a).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
            let (x, y, size) = (num("x"), num("y"), num("font-size"));
            let w = 0.6 * size * t.chars().count() as f64;
            let x0 = match n.attribute("text-anchor") {
                Some("middle") => x - w / 2.0,
                Some("end") => x - w,
                _ => x,
            };
            Some((t, (x0, y - size / 2.0, x0 + w, y + size / 2.0)))
        })
        .collect()
}

/// Tick labels read as round numbers (at most 4 significant digits, no float noise such as
/// 0.30000000000000004 or a trailing `.0`) and no two overlap. Numbers that label points
/// (1, 2, ...) count too: they must not sit on a tick either.
fn check_ticks(path: &Path) {
    let ticks = tick_boxes(path);
    assert!(ticks.len() >= 4, "{}: too few tick labels: {ticks:?}", path.display());
    for (t, _) in &ticks {
        let significant = t.trim_start_matches(['-', '0', '.']).replace('.', "");
        let significant = if t.contains('.') { significant.as_str() } else { significant.trim_end_matches('0') };
        assert!(significant.len() <= 4 && !t.ends_with(".0"), "{}: tick {t:?} is no round number", path.display());
    }
    for (i, (a, ba)) in ticks.iter().enumerate() {
        for (b, bb) in &ticks[i + 1..] {
            let overlap = ba.0 < bb.2 && bb.0 < ba.2 && ba.1 < bb.3 && bb.1 < ba.3;
            assert!(!overlap, "{}: labels {a:?} {ba:?} and {b:?} {bb:?} overlap", path.display());
        }
    }
}

fn check_png(path: &Path) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!((img.width(), img.height()), SIZE);
}

fn write_both(dir: &Path, name: &str, write: impl Fn(&Path)) -> std::path::PathBuf {
    let svg = dir.join(format!("{name}.svg"));
    write(&svg);
    write(&dir.join(format!("{name}.png")));
    check_png(&dir.join(format!("{name}.png")));
    check_ticks(&svg);
    svg
}

#[test]
fn every_chart_kind_as_svg_and_png() {
    let dir = tempfile::tempdir().unwrap();
    let ps = points();

    let sa = chart::speed_accuracy(&ps, AccuracyAxis::Flip).unwrap();
    let texts = svg_texts(&write_both(dir.path(), "speed", |p| sa.write(p).unwrap()));
    // The fastest (multi-source 2 GPUs, 22 ms) and the fastest of the most accurate (fine-all 2
    // GPUs, 0.04 at 30 ms) are undominated.
    assert_eq!(sa.series[0].points.iter().map(|p| (p.0, p.1)).collect::<Vec<_>>(), [(22.0, 0.05), (30.0, 0.04)]);
    // Every point is numbered on the plot and keyed in the legend, dominated ones too, so that
    // points off the front can be told apart.
    for want in [
        "multi-source",
        "fine-all",
        "1",
        "2",
        "3",
        "4",
        "multi-source 2 GPUs",
        "fine-all 2 GPUs",
        "fine-all 1 GPU",
        "frame time (ms)",
        "Pareto front",
    ] {
        assert!(texts.iter().any(|t| t == want), "speed-accuracy SVG lacks {want:?}: {texts:?}");
    }
    assert!(texts.iter().any(|t| t.starts_with("mean FLIP")));

    let scaling = chart::scaling(&ps).unwrap();
    assert_eq!(scaling.series.len(), 4, "measured and ideal per scheme");
    // Ideal: the 1-device time halved at 2 devices.
    assert_eq!(scaling.series[1].points[1].1, 20.0);
    let texts = svg_texts(&write_both(dir.path(), "scaling", |p| scaling.write(p).unwrap()));
    for want in ["multi-source, measured", "multi-source, ideal", "fine-all, ideal", "devices"] {
        assert!(texts.iter().any(|t| t == want), "scaling SVG lacks {want:?}: {texts:?}");
    }

    let views = chart::frame_time_over_views(&ps).unwrap();
    let texts = svg_texts(&write_both(dir.path(), "views", |p| views.write(p).unwrap()));
    assert!(texts.iter().any(|t| t == "views") && texts.iter().any(|t| t == "fine-all"));
    // Series lines (and their legend swatches) are 2 px polylines; axes and ticks 1 px.
    let series_lines =
        |svg: &Path| std::fs::read_to_string(svg).unwrap().matches(r#"stroke-width="2" points="#).count();
    assert!(series_lines(&dir.path().join("views.svg")) > 0, "lines");
    // One view count: points, not a vertical line through them.
    let one = [point("a", "multi-source", 40.0, 0.05, 1, 8), point("b", "multi-source", 22.0, 0.05, 2, 8)];
    let views = chart::frame_time_over_views(&one).unwrap();
    let svg = write_both(dir.path(), "one_view_count", |p| views.write(p).unwrap());
    assert_eq!(series_lines(&svg), 0, "a single view count is drawn as points");

    // Tolerances whose sums are not exact in binary (0.1 + 0.2) tick at round numbers.
    let tolerance_point = |t: f64, missing: f64| Point {
        label: format!("t{t}"),
        case: Some("default".into()),
        missing: Some(missing),
        reprojection_tolerance: Some(t),
        flip: Some(0.05 + t / 10.0),
        ..Default::default()
    };
    let tolerances = [0.05, 0.1, 0.1 + 0.2, 0.7000000000000001, 1.0].map(|t| tolerance_point(t, 0.3 / (1.0 + 9.0 * t)));
    let chart = chart::tolerance(&tolerances, AccuracyAxis::Flip).unwrap();
    write_both(dir.path(), "tolerance", |p| chart.write(p).unwrap());
    let holes: Vec<Point> = (0..6)
        .map(|k| Point {
            label: format!("compact_k{k}"),
            assignment: Some("compact".into()),
            missing: Some(0.001 * (1 + k) as f64),
            hole_fill_ms: Some(1500.0 + 250.0 * k as f64),
            ..Default::default()
        })
        .collect();
    let chart = chart::holes(&holes).unwrap();
    write_both(dir.path(), "holes", |p| chart.write(p).unwrap());

    // Points files round-trip through the documented schema.
    let file = dir.path().join("points.json");
    std::fs::write(&file, serde_json::to_vec(&serde_json::json!({ "points": ps })).unwrap()).unwrap();
    assert_eq!(load_points(&file).unwrap(), ps);
}

#[test]
fn timeline_of_a_chrome_trace() {
    let dir = tempfile::tempdir().unwrap();
    let trace = dir.path().join("trace.json");
    let events = serde_json::json!({ "traceEvents": [
        { "name": "thread_name", "ph": "M", "pid": 0, "tid": 0, "args": { "name": "device 0: lavapipe" } },
        { "name": "thread_name", "ph": "M", "pid": 0, "tid": 1, "args": { "name": "device 1: lavapipe" } },
        { "name": "path_trace", "cat": "pass", "ph": "X", "pid": 0, "tid": 0, "ts": 0.0, "dur": 1500.0, "args": { "frame": 0 } },
        { "name": "path_trace", "cat": "pass", "ph": "X", "pid": 0, "tid": 1, "ts": 100.0, "dur": 1400.0, "args": { "frame": 0 } },
        { "name": "copy out radiance view 1", "cat": "copy_out", "ph": "X", "pid": 0, "tid": 1, "ts": 1500.0, "dur": 200.0, "args": { "frame": 0 } },
        { "name": "copy in radiance view 1", "cat": "copy_in", "ph": "X", "pid": 0, "tid": 0, "ts": 1700.0, "dur": 100.0, "args": { "frame": 0 } },
        { "name": "path_trace", "cat": "pass", "ph": "X", "pid": 0, "tid": 0, "ts": 2000.0, "dur": 1500.0, "args": { "frame": 1 } },
        { "name": "path_trace", "cat": "pass", "ph": "X", "pid": 0, "tid": 1, "ts": 2100.0, "dur": 1400.0, "args": { "frame": 1 } },
    ]});
    std::fs::write(&trace, serde_json::to_vec(&events).unwrap()).unwrap();
    let timeline = Timeline::read(&trace).unwrap();
    assert_eq!(timeline.lanes.len(), 2);
    assert_eq!(timeline.spans.len(), 6);
    assert_eq!(timeline.spans[3].name, "copy_in");
    assert_eq!(timeline.spans[0].end_ms, 1.5);
    assert_eq!(timeline.frames(), [(0, 0.0, 1.8), (1, 2.0, 3.5)]);
    let texts = svg_texts(&write_both(dir.path(), "timeline", |p| timeline.write(p).unwrap()));
    for want in ["device 0: lavapipe", "device 1: lavapipe", "path_trace", "copy_out", "copy_in", "frame 0", "frame 1"]
    {
        assert!(texts.iter().any(|t| t == want), "timeline SVG lacks {want:?}: {texts:?}");
    }
    std::fs::write(&trace, b"{\"traceEvents\": []}").unwrap();
    assert!(Timeline::read(&trace).unwrap_err().to_string().contains("no complete"));
}

#[test]
fn bad_chart_inputs_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("x.json");
    std::fs::write(&file, b"{\"something\": 1}").unwrap();
    assert!(load_points(&file).unwrap_err().to_string().contains("schema"));
    let no_flip = vec![Point { label: "a".into(), frame_ms: Some(1.0), ..Default::default() }];
    assert!(chart::speed_accuracy(&no_flip, AccuracyAxis::Flip).is_err());
    let cased = vec![Point { label: "a".into(), case: Some("nelf".into()), ..Default::default() }];
    let e = of_case(cased.clone(), "multiscopic").unwrap_err().to_string();
    assert!(e.contains("`multiscopic`") && e.contains("the cases are nelf"), "{e}");
    assert_eq!(of_case(cased.clone(), "nelf").unwrap(), cased);
    let sa = chart::speed_accuracy(&points(), AccuracyAxis::Psnr).unwrap();
    assert!(sa.write(&dir.path().join("chart.jpg")).unwrap_err().to_string().contains(".svg or .png"));
}
