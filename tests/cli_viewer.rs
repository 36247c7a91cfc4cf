//! `render`'s pictures as a person sees them: `viewer.html` in a real browser (Debian's headless
//! Chromium, installed by .ci/setup.sh), opened from file:// with a view chosen through the
//! page's own URL fragment, its screenshot compared with that view's PNG; the views' PNGs at
//! the automatic exposure; the wiggle's frames.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::{parallax_in, scratch};

fn render(dir: &Path, args: &[&str]) {
    let out = parallax_in(dir, &[&["render", "--spp", "2", "--still", "--out-dir", "lf"], args].concat());
    assert!(out.status.success(), "render {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

/// Headless Chromium on `page` (a file URL with its fragment); `what` is `--screenshot=FILE` or
/// `--dump-dom`. Fails, naming the fix, when Chromium is not installed.
fn chromium(dir: &Path, page: &str, what: &str, window: (u32, u32)) -> Output {
    let out = Command::new("timeout")
        .arg("120")
        .arg("chromium")
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--force-device-scale-factor=1"])
        .arg("--virtual-time-budget=5000")
        // The controls test drives the page from a harness page on file:// around it.
        .arg("--allow-file-access-from-files")
        .arg(format!("--user-data-dir={}", dir.join("chromium-profile").display()))
        .arg(format!("--window-size={},{}", window.0, window.1))
        .arg(what)
        .arg(page)
        .current_dir(dir)
        .output()
        .expect("cannot run `timeout chromium`: install Debian's chromium (bash .ci/setup.sh)");
    assert!(out.status.success(), "chromium {what}: {}", String::from_utf8_lossy(&out.stderr));
    out
}

fn png(path: &Path) -> image::RgbImage {
    image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8()
}

/// The largest channel difference between `view` and the `zoom`× magnified copy of it whose
/// top-left corner is at `at` in `shot` (each view pixel read at its block's centre).
fn max_difference(shot: &image::RgbImage, at: (u32, u32), zoom: u32, view: &image::RgbImage) -> u8 {
    let mut worst = 0;
    for (x, y, p) in view.enumerate_pixels() {
        let q = shot.get_pixel(at.0 + x * zoom + zoom / 2, at.1 + y * zoom + zoom / 2);
        for c in 0..3 {
            worst = worst.max(p[c].abs_diff(q[c]));
        }
    }
    worst
}

/// Opens lf/viewer.html at view 0 in a frame, then presses keys and moves the pointer over the
/// image (fractions of its width and height), logging the view the page shows after each.
const HARNESS: &str = r#"<!doctype html><html><body>
<iframe id="f" src="lf/viewer.html#view=0&zoom=2" width="480" height="360"></iframe><pre id="out"></pre>
<script>
const frame = document.getElementById("f");
frame.addEventListener("load", () => {
  const w = frame.contentWindow, d = frame.contentDocument, log = [];
  const key = (k) => { w.dispatchEvent(new w.KeyboardEvent("keydown", { key: k })); log.push(`${k}=${d.body.dataset.view}`); };
  ["ArrowRight", "ArrowRight", "ArrowDown", "ArrowLeft", "ArrowUp"].forEach(key);
  const r = d.getElementById("eye0").getBoundingClientRect();
  const move = (fx, fy) => {
    const at = { clientX: r.left + fx * r.width, clientY: r.top + fy * r.height, bubbles: true };
    d.getElementById("stage").dispatchEvent(new w.PointerEvent("pointermove", at));
    log.push(`move(${fx},${fy})=${d.body.dataset.view}`);
  };
  move(0.9, 0.9); move(0.1, 0.1); move(0.6, 0.2);
  log.push(`hash=${w.location.hash}`);
  document.getElementById("out").textContent = log.join(" ");
});
</script></body></html>"#;

/// Tolerance of a browser's copy of an sRGB PNG: 8-bit sRGB shown on an sRGB screen is
/// unchanged in principle; 2 levels allow for a colour-managed round trip.
const TOLERANCE: u8 = 2;

#[test]
fn the_viewer_shows_the_view_its_url_names() {
    let dir = scratch("viewer", "grid");
    render(&dir, &["--lf", "4x2", "--resolution", "24x16", "--spacing", "0.3", "--wiggle", "wiggle.png"]);
    let lf = dir.join("lf");
    let page = format!("file://{}#view=5&zoom=2", lf.join("viewer.html").display());
    let shot_path = dir.join("shot.png");
    chromium(&dir, &page, &format!("--screenshot={}", shot_path.display()), (480, 360));
    let shot = png(&shot_path);
    let view = |k: u32| png(&lf.join(format!("view_{k:03}.png")));
    let seen = max_difference(&shot, (0, 0), 2, &view(5));
    assert!(seen <= TOLERANCE, "the page at #view=5 differs from view_005.png by {seen} levels");
    // The comparison can fail: the neighbouring view is another picture.
    assert!(max_difference(&shot, (0, 0), 2, &view(4)) > TOLERANCE, "views 4 and 5 look alike");

    // The page's own state and the run's settings, as the DOM shows them once its script ran.
    let dom = String::from_utf8_lossy(&chromium(&dir, &page, "--dump-dom", (480, 360)).stdout).into_owned();
    assert!(dom.contains(r#"data-view="5""#), "{dom}");
    assert!(dom.contains("view 5 (of 0–7) · column 2 of 4 · row 2 of 2 · zoom 2×"), "{dom}");
    for setting in ["4x2 (8 views, 4×2), 24×16 pixels per view", "reproject, multi-source", "(auto)", "still"] {
        assert!(dom.contains(setting), "the settings show '{setting}'");
    }
    // The page's own controls: keys step through the grid, the pointer's place picks the view,
    // and the URL follows. A harness page beside it sends the events into it.
    let harness = dir.join("harness.html");
    std::fs::write(&harness, HARNESS).unwrap();
    let dom = chromium(&dir, &format!("file://{}", harness.display()), "--dump-dom", (640, 480)).stdout;
    let dom = String::from_utf8_lossy(&dom);
    let log = dom.split("<pre id=\"out\">").nth(1).and_then(|s| s.split("</pre>").next()).unwrap_or("");
    assert_eq!(
        log,
        "ArrowRight=1 ArrowRight=2 ArrowDown=6 ArrowLeft=5 ArrowUp=1 move(0.9,0.9)=7 move(0.1,0.1)=0 \
         move(0.6,0.2)=2 hash=#view=2&amp;zoom=2",
        "{dom}"
    );
    // Small views are embedded: the page is one file.
    let html = std::fs::read_to_string(lf.join("viewer.html")).unwrap();
    assert_eq!(html.matches("data:image/png;base64,").count(), 8);

    // The wiggle sweeps the middle row (views 4..=7) there and back, each frame a view's PNG.
    let file = std::fs::File::open(dir.join("wiggle.png")).unwrap();
    let mut reader = png::Decoder::new(std::io::BufReader::new(file)).read_info().unwrap();
    assert_eq!(reader.info().animation_control.unwrap().num_frames, 6);
    let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
    for k in [4, 5, 6, 7, 6, 5] {
        reader.next_frame(&mut buffer).unwrap();
        assert!(buffer == view(k).into_raw(), "a wiggle frame is not view {k}");
    }
}

#[test]
fn the_nelf_viewer_shows_both_eyes_side_by_side() {
    let dir = scratch("viewer", "nelf");
    render(&dir, &["--lf", "nelf", "--resolution", "16x16", "--spacing", "0.01", "--pipeline", "path-trace"]);
    let lf = dir.join("lf");
    // View 45: row 3, column 9, the right eye's column 3; the left eye's is view 39.
    let page = format!("file://{}#view=45&zoom=1", lf.join("viewer.html").display());
    let shot_path = dir.join("shot.png");
    chromium(&dir, &page, &format!("--screenshot={}", shot_path.display()), (320, 240));
    let shot = png(&shot_path);
    let view = |k: u32| png(&lf.join(format!("view_{k:03}.png")));
    let gap = 8;
    assert!(max_difference(&shot, (0, 0), 1, &view(39)) <= TOLERANCE, "the left eye shows view 39");
    assert!(max_difference(&shot, (16 + gap, 0), 1, &view(45)) <= TOLERANCE, "the right eye shows view 45");
    assert!(max_difference(&shot, (16 + gap, 0), 1, &view(39)) > TOLERANCE, "the eyes look alike");
    let dom = String::from_utf8_lossy(&chromium(&dir, &page, "--dump-dom", (320, 240)).stdout).into_owned();
    assert!(dom.contains("column 4 of 6 · row 4 of 6") && dom.contains("left eye view 39, right eye view 45"), "{dom}");
}
