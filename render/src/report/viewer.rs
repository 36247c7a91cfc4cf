//! `viewer.html`: a light field as a person looks at one, in any browser, with no network and
//! no build step. Moving the mouse over the image (or dragging it) moves smoothly through the
//! views: across for the column, down for the row (a 1D light field such as multiscopic has one
//! row), the picture between views a bilinear blend of the four around the pointer. Refocusing
//! sums the views within an aperture, each shifted so that a chosen plane lines up
//! (shift-and-add, from the views' places in [`ViewGeometry`]). The NELF preset's two eye
//! blocks are a stereo pair at a size that can be fused, or a red/cyan anaglyph (`e` switches
//! to one image over all twelve columns). Arrow keys step, `+`/`-` zoom, space plays a sweep,
//! and the URL fragment (`#view=K&zoom=Z`, `col`/`row` between views, `focus`/`aperture`,
//! `stereo=anaglyph`) selects what is shown (the page keeps it up to date, so a link shares it).
//! The page draws on 2D canvases with `drawImage` alone: it never reads pixels back, which a
//! browser refuses for images loaded from files, and needs no WebGL.
//!
//! The views are the PNGs written beside the page: embedded as data URIs while they total at
//! most [`EMBED_LIMIT_BYTES`] (the page is then one file to send), else referred to by name
//! (the page then lives beside them).

use base64::Engine as _;
use parallax_graph::LightField;

/// Most bytes of PNG views embedded in the page: above it a browser parses megabytes of base64
/// before it shows anything, so the page refers to the files instead.
pub const EMBED_LIMIT_BYTES: usize = 8 << 20;

pub const TEMPLATE: &str = include_str!("viewer.html");

/// Where the views looked from, for refocusing on the page. A point at depth `z` (metres along
/// the rig's forward axis) appears `focal_px · p · (1/focus_m − 1/z)` pixels from where the rig
/// centre sees it in the view at `p` (right for +x; up, so fewer rows, for +y): the views are
/// off-axis cameras whose zero-disparity plane is at `focus_m`.
pub struct ViewGeometry {
    /// Each view's place on the camera plane, metres, x right and y up, in view order.
    pub positions: Vec<[f64; 2]>,
    /// Focal length in pixels: half the image height over the tangent of half the vertical
    /// field of view.
    pub focal_px: f64,
    /// Distance of the zero-disparity plane, metres.
    pub focus_m: f64,
}

impl ViewGeometry {
    pub fn of(lf: &LightField) -> Self {
        ViewGeometry {
            positions: lf.views().map(|v| lf.position(v).to_array()).collect(),
            focal_px: lf.height as f64 * 0.5 / (lf.rig.yfov * 0.5).tan(),
            focus_m: lf.rig.focus_distance,
        }
    }
}

/// What the page shows: the grid, one view's size, how many columns one eye has (`cols` for one
/// eye), the views' places, and the views' PNGs in view order with their file names beside the
/// page.
pub struct ViewerPage<'a> {
    pub title: String,
    pub cols: u32,
    pub rows: u32,
    pub width: u32,
    pub height: u32,
    pub eye_cols: u32,
    pub geometry: ViewGeometry,
    /// (file name beside the page, PNG bytes) per view.
    pub views: &'a [(String, Vec<u8>)],
    /// The run's settings as (name, value) rows.
    pub settings: Vec<(String, String)>,
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// Each view's image source: data URIs under [`EMBED_LIMIT_BYTES`] in all, file names above.
fn sources(views: &[(String, Vec<u8>)], limit: usize) -> Vec<String> {
    let total: usize = views.iter().map(|(_, png)| png.len()).sum();
    if total <= limit {
        let b64 = base64::engine::general_purpose::STANDARD;
        views.iter().map(|(_, png)| format!("data:image/png;base64,{}", b64.encode(png))).collect()
    } else {
        views.iter().map(|(name, _)| name.clone()).collect()
    }
}

impl ViewerPage<'_> {
    pub fn html(&self) -> String {
        self.html_with_limit(EMBED_LIMIT_BYTES)
    }

    fn html_with_limit(&self, limit: usize) -> String {
        let light_field = serde_json::json!({
            "cols": self.cols, "rows": self.rows, "width": self.width, "height": self.height,
            "eyeCols": self.eye_cols, "views": sources(self.views, limit),
            "positions": self.geometry.positions, "focalPx": self.geometry.focal_px,
            "focus": self.geometry.focus_m,
        });
        // `</` cannot end the script early inside a JSON string written as `<\/`.
        let light_field = light_field.to_string().replace("</", "<\\/");
        let settings: String = self
            .settings
            .iter()
            .map(|(k, v)| format!("<tr><td>{}</td><td>{}</td></tr>", escape(k), escape(v)))
            .collect::<Vec<_>>()
            .join("\n");
        let row_keys = if self.rows > 1 { " <kbd>↑</kbd> <kbd>↓</kbd>" } else { "" };
        let eye_key = if self.eye_cols < self.cols {
            "; <kbd>e</kbd> shows both eyes or one, <kbd>a</kbd> the eyes as a red/cyan anaglyph"
        } else {
            ""
        };
        TEMPLATE
            .replace("__TITLE__", &escape(&self.title))
            .replace("__ROW_KEYS__", row_keys)
            .replace("__EYE_KEY__", eye_key)
            .replace("__SETTINGS__", &settings)
            .replace("__LIGHT_FIELD__", &light_field)
    }
}

/// A number to four significant digits, trailing zeros dropped (JSON carries every digit of an
/// f32 or f64).
fn significant(v: &serde_json::Value) -> String {
    match v.as_f64() {
        Some(x) if x != 0.0 && x.is_finite() => {
            let digits = (3 - x.abs().log10().floor() as i32).max(0) as usize;
            let text = format!("{x:.digits$}");
            if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.').to_string() } else { text }
        }
        Some(x) => x.to_string(),
        None => "—".into(),
    }
}

/// The rows of the settings table, from render.json: what was rendered, how, and how fast.
pub fn settings_of_render_json(json: &serde_json::Value) -> Vec<(String, String)> {
    let text = |v: &serde_json::Value| match v {
        serde_json::Value::String(s) => s.clone(),
        serde_json::Value::Null => "—".into(),
        other => other.to_string(),
    };
    let layout = &json["layout"];
    let devices = json["devices"].as_array().map_or(0, Vec::len);
    let mut rows = vec![
        ("scene".into(), text(&json["scene"])),
        (
            "light field".into(),
            format!(
                "{} ({} views, {}×{}), {}×{} pixels per view",
                text(&json["setup"]["lf"]),
                text(&layout["views"]),
                text(&layout["cols"]),
                text(&layout["rows"]),
                text(&layout["width"]),
                text(&layout["height"])
            ),
        ),
        (
            "spacing, focus".into(),
            format!("{} m, {} m", significant(&json["setup"]["spacing_m"]), significant(&json["setup"]["focus_m"])),
        ),
        ("pipeline".into(), format!("{}, {}, {} device(s)", text(&json["pipeline"]), text(&json["scheme"]), devices)),
        ("samples".into(), format!("{} spp, max depth {}", text(&json["spp"]), text(&json["max_depth"]))),
        ("denoise".into(), text(&json["denoise"])),
        ("exposure".into(), format!("{} ({})", significant(&json["exposure"]), text(&json["exposure_mode"]))),
        (
            "frames".into(),
            format!(
                "{} measured after {} warm-up, camera {}",
                text(&json["frames"]),
                text(&json["warmup"]),
                if json["setup"]["still"] == true { "still" } else { "moving (these are the last frame's views)" }
            ),
        ),
    ];
    if let Some(ms) = json["timing"]["frame_gpu"]["median_ms"].as_f64() {
        rows.push(("frame time".into(), format!("{ms:.2} ms median (GPU)")));
    }
    if let Some(missing) = json["missing_pixels"]["overall"].as_f64() {
        rows.push(("missing pixels".into(), format!("{:.2} %", 100.0 * missing)));
    }
    if let Some(version) = json["version"].as_str() {
        rows.push(("parallax".into(), version.into()));
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;

    use glam::{DVec2, DVec3};
    use parallax_graph::{LayoutSpec, Rig, ViewId};

    fn page(views: &[(String, Vec<u8>)]) -> ViewerPage<'_> {
        ViewerPage {
            title: "a <test>".into(),
            cols: 2,
            rows: 1,
            width: 4,
            height: 3,
            eye_cols: 2,
            geometry: ViewGeometry { positions: vec![[-0.5, 0.0], [0.5, 0.0]], focal_px: 2.0, focus_m: 3.0 },
            views,
            settings: vec![("scene".into(), "x&y".into())],
        }
    }

    #[test]
    fn small_views_are_embedded_and_large_ones_referred_to() {
        let views = vec![("view_000.png".to_string(), vec![1u8, 2, 3]), ("view_001.png".to_string(), vec![4u8; 10])];
        let embedded = page(&views).html_with_limit(13);
        assert!(embedded.contains("\"data:image/png;base64,AQID\""), "three bytes 1, 2, 3 in base64");
        assert!(!embedded.contains("view_000.png"));
        let referred = page(&views).html_with_limit(12);
        assert!(referred.contains(r#""views":["view_000.png","view_001.png"]"#), "{referred}");
        assert!(referred.contains(r#""positions":[[-0.5,0.0],[0.5,0.0]]"#), "{referred}");
        assert!(!referred.contains("data:image"));
        // Text is escaped, and no placeholder is left.
        assert!(referred.contains("<title>a &lt;test&gt;</title>") && referred.contains("<td>x&amp;y</td>"));
        assert!(!referred.contains("__"), "a placeholder is left");
        // One row: no up and down keys, no eye switch.
        assert!(!referred.contains("<kbd>↑</kbd>") && !referred.contains("<kbd>e</kbd>"));
    }

    #[test]
    fn numbers_show_four_significant_digits() {
        let show = |x: f64| significant(&serde_json::json!(x));
        assert_eq!(
            (show(6.382213115692139), show(0.001), show(0.593058), show(1234.4)),
            ("6.382".into(), "0.001".into(), "0.5931".into(), "1234".into())
        );
        assert_eq!(show(0.2), "0.2");
    }

    /// The page's shift-and-add moves each view by `focal_px · Δp · (1/focus − 1/z)`: that is
    /// where the views' cameras put a point at depth `z`, on a grid and on NELF's two blocks.
    #[test]
    fn the_pages_shifts_are_the_cameras_parallax() {
        let rig = Rig { focus_distance: 2.5, yfov: 0.7, ..Rig::default() };
        for spec in [LayoutSpec::Grid { cols: 3, rows: 2 }, LayoutSpec::Nelf] {
            let lf = LightField::new(spec, Some(0.2), Some((64, 40)), rig).unwrap();
            let geometry = ViewGeometry::of(&lf);
            for (z, offset) in [(6.0, DVec3::new(0.3, -0.2, 0.0)), (1.5, DVec3::new(-0.1, 0.25, 0.0))] {
                let point = rig.eye + rig.forward * z + offset;
                let pixel = |v: usize| {
                    let ndc = lf.camera(ViewId(v as u32)).project(point).unwrap();
                    DVec2::new((ndc.x + 1.0) * 0.5 * 64.0, (1.0 - ndc.y) * 0.5 * 40.0)
                };
                let k = geometry.focal_px * (1.0 / geometry.focus_m - 1.0 / z);
                let [x0, y0] = geometry.positions[0];
                for (v, &[x, y]) in geometry.positions.iter().enumerate() {
                    let expected = DVec2::new(k * (x - x0), -k * (y - y0));
                    let moved = pixel(v) - pixel(0);
                    assert!((moved - expected).length() < 1e-9, "view {v} at depth {z}: {moved} ≠ {expected}");
                }
            }
        }
    }
}
