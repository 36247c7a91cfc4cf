//! `render`'s pictures as a person sees them: `viewer.html` in a real browser (Debian's headless
//! Chromium, installed by .ci/setup.sh, with `--disable-gpu`: the page's 2D canvas path),
//! opened from file:// with what to show chosen through the page's own URL fragment, its
//! screenshot compared with the views' PNGs: one view, a blend between two, a refocused
//! picture, a stereo pair and an anaglyph; the wiggle's frames.

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

/// Where the page puts pictures `across` × `down` pixels wide and high (a stereo pair's two
/// and the gap between them together) in a `window`: centred across, and centred in the
/// stage, the window's top 70 %.
fn centred(window: (u32, u32), across: u32, down: u32) -> (u32, u32) {
    ((window.0 - across) / 2, (window.1 * 7 / 10 - down) / 2)
}

/// The `size` picture shown `zoom`× magnified with its top-left corner at `at` in `shot`, each
/// pixel read at its block's centre.
fn shown(shot: &image::RgbImage, at: (u32, u32), zoom: u32, size: (u32, u32)) -> image::RgbImage {
    image::RgbImage::from_fn(size.0, size.1, |x, y| {
        *shot.get_pixel(at.0 + x * zoom + zoom / 2, at.1 + y * zoom + zoom / 2)
    })
}

/// The largest channel difference between two pictures of one size.
fn max_difference(a: &image::RgbImage, b: &image::RgbImage) -> u8 {
    a.pixels().zip(b.pixels()).flat_map(|(p, q)| (0..3).map(move |c| p[c].abs_diff(q[c]))).max().unwrap()
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
  move(0.9, 0.9); move(0.1, 0.1); move(0.5, 0.75); move(0.6, 0.2);
  log.push(`hash=${w.location.hash}`);
  document.getElementById("out").textContent = log.join(" ");
});
</script></body></html>"#;

/// Tolerance of a browser's copy of an sRGB PNG: 8-bit sRGB shown on an sRGB screen is
/// unchanged in principle; 2 levels allow for a colour-managed round trip.
const TOLERANCE: u8 = 2;

#[test]
fn the_viewer_shows_a_view_or_a_blend_of_two_as_its_url_or_the_pointer_names() {
    let dir = scratch("viewer", "grid");
    render(&dir, &["--lf", "4x2", "--resolution", "24x16", "--spacing", "0.3", "--wiggle", "wiggle.png"]);
    let lf = dir.join("lf");
    let page = format!("file://{}#view=5&zoom=2", lf.join("viewer.html").display());
    let shot_path = dir.join("shot.png");
    chromium(&dir, &page, &format!("--screenshot={}", shot_path.display()), (480, 360));
    let view = |k: u32| png(&lf.join(format!("view_{k:03}.png")));
    // The picture is centred in the window.
    let picture = shown(&png(&shot_path), centred((480, 360), 48, 32), 2, (24, 16));
    let seen = max_difference(&picture, &view(5));
    assert!(seen <= TOLERANCE, "the page at #view=5 differs from view_005.png by {seen} levels");
    // The comparison can fail: the neighbouring view is another picture.
    assert!(max_difference(&picture, &view(4)) > TOLERANCE, "views 4 and 5 look alike");

    // The page's own state and the run's settings, as the DOM shows them once its script ran.
    let dom = String::from_utf8_lossy(&chromium(&dir, &page, "--dump-dom", (480, 360)).stdout).into_owned();
    assert!(dom.contains(r#"data-view="5""#), "{dom}");
    assert!(dom.contains("view 5 (of 0–7) · column 2 of 4 · row 2 of 2 · zoom 2×"), "{dom}");
    for setting in ["4x2 (8 views, 4×2), 24×16 pixels per view", "reproject, multi-source", "(auto)", "still"] {
        assert!(dom.contains(setting), "the settings show '{setting}'");
    }
    // The page's own controls: keys step through the grid, the pointer's place picks the place
    // on the grid (each view's centre in the middle of its share of the image, fractions between
    // views, the view shown the nearest), and the URL follows. A harness page beside it sends
    // the events into it.
    let harness = dir.join("harness.html");
    std::fs::write(&harness, HARNESS).unwrap();
    let dom = chromium(&dir, &format!("file://{}", harness.display()), "--dump-dom", (640, 480)).stdout;
    let dom = String::from_utf8_lossy(&dom);
    let log = dom.split("<pre id=\"out\">").nth(1).and_then(|s| s.split("</pre>").next()).unwrap_or("");
    assert_eq!(
        log,
        "ArrowRight=1 ArrowRight=2 ArrowDown=6 ArrowLeft=5 ArrowUp=1 move(0.9,0.9)=7 move(0.1,0.1)=0 \
         move(0.5,0.75)=6 move(0.6,0.2)=2 hash=#col=1.9&amp;row=0&amp;zoom=2",
        "{dom}"
    );
    // Between two views the page blends them: at `#col=1.5&row=1` each pixel lies between views
    // 5 and 6's, and the picture is neither. The pointer halfway between the two views' shares
    // of the image shows the same picture.
    let page = format!("file://{}#col=1.5&row=1&zoom=2", lf.join("viewer.html").display());
    chromium(&dir, &page, &format!("--screenshot={}", shot_path.display()), (480, 360));
    let at = centred((480, 360), 48, 32);
    let blend = shown(&png(&shot_path), at, 2, (24, 16));
    let (a, b) = (view(5), view(6));
    for (x, y, p) in blend.enumerate_pixels() {
        for c in 0..3 {
            let (lo, hi) =
                (a.get_pixel(x, y)[c].min(b.get_pixel(x, y)[c]), a.get_pixel(x, y)[c].max(b.get_pixel(x, y)[c]));
            assert!(
                lo.saturating_sub(TOLERANCE) <= p[c] && p[c] <= hi.saturating_add(TOLERANCE),
                "pixel ({x}, {y}) channel {c}: {} is not between views 5 and 6's {lo} and {hi}",
                p[c]
            );
        }
    }
    assert!(max_difference(&blend, &a) > TOLERANCE && max_difference(&blend, &b) > TOLERANCE, "the blend is a view");

    // A page filling the window moves the pointer to the middle of the image (column 1.5) and
    // three quarters down (row 1) in the viewer inside it.
    let harness = dir.join("pointer.html");
    std::fs::write(
        &harness,
        r#"<!doctype html><html><body style="margin:0">
<iframe id="f" src="lf/viewer.html#view=0&zoom=2" style="position:fixed;left:0;top:0;width:100%;height:100%;border:0"></iframe>
<script>
const frame = document.getElementById("f");
frame.addEventListener("load", () => {
  const w = frame.contentWindow, d = frame.contentDocument, r = d.getElementById("eye0").getBoundingClientRect();
  const at = { clientX: r.left + 0.5 * r.width, clientY: r.top + 0.75 * r.height, bubbles: true };
  d.getElementById("stage").dispatchEvent(new w.PointerEvent("pointermove", at));
});
</script></body></html>"#,
    )
    .unwrap();
    chromium(
        &dir,
        &format!("file://{}", harness.display()),
        &format!("--screenshot={}", shot_path.display()),
        (480, 360),
    );
    let pointed = shown(&png(&shot_path), at, 2, (24, 16));
    assert!(pointed == blend, "the pointer between views 5 and 6 shows another picture than #col=1.5&row=1");

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
fn the_nelf_viewer_shows_a_stereo_pair_and_an_anaglyph() {
    let dir = scratch("viewer", "nelf");
    render(&dir, &["--lf", "nelf", "--resolution", "16x16", "--spacing", "0.01", "--pipeline", "path-trace"]);
    let lf = dir.join("lf");
    let view = |k: u32| png(&lf.join(format!("view_{k:03}.png")));
    // View 45: row 3, column 9, the right eye's column 3; the left eye's is view 39. The pair
    // is centred, 8 pixels apart.
    let page = format!("file://{}#view=45&zoom=1", lf.join("viewer.html").display());
    let shot_path = dir.join("shot.png");
    chromium(&dir, &page, &format!("--screenshot={}", shot_path.display()), (320, 240));
    let shot = png(&shot_path);
    let (x, y) = centred((320, 240), 16 + 8 + 16, 16);
    let (left, right) = (shown(&shot, (x, y), 1, (16, 16)), shown(&shot, (x + 16 + 8, y), 1, (16, 16)));
    assert!(max_difference(&left, &view(39)) <= TOLERANCE, "the left eye shows view 39");
    assert!(max_difference(&right, &view(45)) <= TOLERANCE, "the right eye shows view 45");
    assert!(max_difference(&right, &view(39)) > TOLERANCE, "the eyes look alike");
    let dom = String::from_utf8_lossy(&chromium(&dir, &page, "--dump-dom", (320, 240)).stdout).into_owned();
    assert!(dom.contains("column 4 of 6 · row 4 of 6") && dom.contains("left eye view 39, right eye view 45"), "{dom}");

    // Fitted to a large window, each eye is at most 230 pixels wide (the pair's centres an eye
    // distance apart, so that it can be fused), not half the window.
    let page = format!("file://{}#view=45", lf.join("viewer.html").display());
    let dom = String::from_utf8_lossy(&chromium(&dir, &page, "--dump-dom", (1280, 800)).stdout).into_owned();
    assert!(dom.contains("right eye view 45 · zoom 14×"), "230 / 16 pixels: {dom}");

    // The anaglyph: one centred picture, red from the left eye, green and blue from the right.
    let page = format!("file://{}#view=45&zoom=1&stereo=anaglyph", lf.join("viewer.html").display());
    chromium(&dir, &page, &format!("--screenshot={}", shot_path.display()), (320, 240));
    let anaglyph = shown(&png(&shot_path), centred((320, 240), 16, 16), 1, (16, 16));
    let channels = |picture: &image::RgbImage, channels: &[usize]| -> Vec<u8> {
        picture.pixels().flat_map(|p| channels.iter().map(|&c| p[c]).collect::<Vec<_>>()).collect()
    };
    let most_apart = |a: &[u8], b: &[u8]| a.iter().zip(b).map(|(p, q)| p.abs_diff(*q)).max().unwrap();
    let (red, cyan) = (&[0][..], &[1, 2][..]);
    assert!(most_apart(&channels(&anaglyph, red), &channels(&view(39), red)) <= TOLERANCE, "red is the left eye's");
    assert!(most_apart(&channels(&anaglyph, cyan), &channels(&view(45), cyan)) <= TOLERANCE, "cyan is the right eye's");
    // Either check can fail: each eye's channels differ from the other eye's.
    assert!(most_apart(&channels(&anaglyph, red), &channels(&view(45), red)) > TOLERANCE, "the eyes' reds look alike");
    assert!(
        most_apart(&channels(&anaglyph, cyan), &channels(&view(39), cyan)) > TOLERANCE,
        "the eyes' cyans look alike"
    );
}

/// Two emissive checkerboards facing the camera at the origin (looking down −z): a near one at
/// depth 2 m left of the axis and a far one at 4 m right of it, as a glTF with its buffer in a
/// data URI. Emission alone lights them (black base colour), so they look the same from every
/// view and need no sky.
fn two_boards_gltf() -> String {
    use base64::Engine as _;
    // (depth, left, bottom, square size, squares across, squares up)
    let boards = [(2.0f32, -1.0f32, -0.75f32, 0.25f32, 3, 6), (4.0, 0.5, -1.5, 0.5, 4, 6)];
    let mut bytes = Vec::new();
    let (mut accessors, mut views, mut primitives) = (Vec::new(), Vec::new(), Vec::new());
    for (material, parity) in [0, 1].into_iter().enumerate() {
        let (mut positions, mut indices) = (Vec::<[f32; 3]>::new(), Vec::<u32>::new());
        for &(depth, left, bottom, size, across, up) in &boards {
            for (i, j) in (0..across).flat_map(|i| (0..up).map(move |j| (i, j))).filter(|(i, j)| (i + j) % 2 == parity)
            {
                let (x, y) = (left + i as f32 * size, bottom + j as f32 * size);
                let first = positions.len() as u32;
                positions.extend([
                    [x, y, -depth],
                    [x + size, y, -depth],
                    [x + size, y + size, -depth],
                    [x, y + size, -depth],
                ]);
                indices.extend([first, first + 1, first + 2, first, first + 2, first + 3]);
            }
        }
        let normals = vec![[0.0f32, 0.0, 1.0]; positions.len()];
        let (min, max) = positions.iter().fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), p| {
            (std::array::from_fn(|c| lo[c].min(p[c])), std::array::from_fn(|c| hi[c].max(p[c])))
        });
        let mut add = |data: Vec<u8>, count: usize, kind: &str, component: u32, extra: serde_json::Value| {
            views.push(serde_json::json!({ "buffer": 0, "byteOffset": bytes.len(), "byteLength": data.len() }));
            bytes.extend(data);
            let mut accessor = serde_json::json!({ "bufferView": views.len() - 1, "componentType": component, "count": count, "type": kind });
            accessor.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
            accessors.push(accessor);
            accessors.len() - 1
        };
        let floats = |v: &[[f32; 3]]| v.iter().flatten().flat_map(|f| f.to_le_bytes()).collect::<Vec<u8>>();
        let position =
            add(floats(&positions), positions.len(), "VEC3", 5126, serde_json::json!({ "min": min, "max": max }));
        let normal = add(floats(&normals), normals.len(), "VEC3", 5126, serde_json::json!({}));
        let index = add(
            indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
            indices.len(),
            "SCALAR",
            5125,
            serde_json::json!({}),
        );
        primitives.push(serde_json::json!({ "attributes": { "POSITION": position, "NORMAL": normal }, "indices": index, "material": material }));
    }
    let material = |name: &str, emission: f32| {
        serde_json::json!({ "name": name, "emissiveFactor": [emission, emission, emission],
            "pbrMetallicRoughness": { "baseColorFactor": [0.0, 0.0, 0.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0 } })
    };
    let b64 = base64::engine::general_purpose::STANDARD.encode(&bytes);
    serde_json::json!({
        "asset": { "version": "2.0" }, "scene": 0, "scenes": [{ "nodes": [0] }], "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": primitives }], "materials": [material("bright", 1.0), material("dark", 0.15)],
        "buffers": [{ "byteLength": bytes.len(), "uri": format!("data:application/octet-stream;base64,{b64}") }],
        "bufferViews": views, "accessors": accessors,
    })
    .to_string()
}

/// Refocusing at a board's depth makes that board sharp: over a 3×3 grid 0.5 m apart, focused
/// (zero disparity) at 3 m between the boards, the views see the near board 4 pixels and the far
/// one 2 pixels apart per step. Refocused from the centre with every view summed, the board in
/// focus equals the centre view (each view shifted onto it), and the other is blurred.
#[test]
fn refocusing_at_a_planes_depth_makes_it_sharp() {
    let dir = scratch("viewer", "refocus");
    std::fs::write(dir.join("boards.gltf"), two_boards_gltf()).unwrap();
    // yfov 2·atan(1/2): the focal length is the image height, 48 pixels; 6-pixel squares.
    render(
        &dir,
        &[
            "--scene",
            "boards.gltf",
            "--camera",
            "0,0,0,0,0,-1,0,1,0,53.13010235415598",
            "--focus",
            "3",
            "--lf",
            "3x3",
            "--spacing",
            "0.5",
            "--resolution",
            "64x48",
            "--pipeline",
            "path-trace",
            "--no-denoise",
            "--exposure",
            "1",
        ],
    );
    let lf = dir.join("lf");
    let centre = png(&lf.join("view_004.png"));
    // Inside each board's squares in the centre view (columns, rows), a pixel in from its edges.
    let (near, far) = ((9..25, 7..41), (39..61, 7..41));
    let mean_difference = |picture: &image::RgbImage, (xs, ys): &(std::ops::Range<u32>, std::ops::Range<u32>)| {
        let mut sum = 0u32;
        for (x, y) in xs.clone().flat_map(|x| ys.clone().map(move |y| (x, y))) {
            sum += (0..3).map(|c| picture.get_pixel(x, y)[c].abs_diff(centre.get_pixel(x, y)[c]) as u32).sum::<u32>();
        }
        sum as f64 / (3 * xs.len() * ys.len()) as f64
    };
    let shot_path = dir.join("shot.png");
    let refocused = |depth: &str| {
        let page = format!("file://{}#view=4&zoom=2&focus={depth}", lf.join("viewer.html").display());
        chromium(&dir, &page, &format!("--screenshot={}", shot_path.display()), (320, 240));
        shown(&png(&shot_path), centred((320, 240), 128, 96), 2, (64, 48))
    };
    let at_near = refocused("2");
    let at_far = refocused("4");
    let (sharp, blurred) = (mean_difference(&at_near, &near), mean_difference(&at_near, &far));
    assert!(
        sharp <= 2.0 && blurred >= 20.0,
        "focused at 2 m: near board {sharp} levels from the centre view, far {blurred}"
    );
    let (sharp, blurred) = (mean_difference(&at_far, &far), mean_difference(&at_far, &near));
    assert!(
        sharp <= 2.0 && blurred >= 20.0,
        "focused at 4 m: far board {sharp} levels from the centre view, near {blurred}"
    );

    // The default aperture sums every view from the grid's middle; one of half a view sums the
    // centre view alone, a pinhole camera: both boards sharp.
    let page = format!("file://{}#view=4&focus=2", lf.join("viewer.html").display());
    let dom = String::from_utf8_lossy(&chromium(&dir, &page, "--dump-dom", (320, 240)).stdout).into_owned();
    assert!(dom.contains("view 4 (of 0–8) · column 2 of 3 · row 2 of 3 · focus 2 m, 9 views"), "{dom}");
    let pinhole = refocused("2&aperture=0.5");
    let (at_near, at_far) = (mean_difference(&pinhole, &near), mean_difference(&pinhole, &far));
    assert!(
        at_near <= 2.0 && at_far <= 2.0,
        "an aperture of half a view: boards {at_near} and {at_far} levels from the centre view"
    );
}
