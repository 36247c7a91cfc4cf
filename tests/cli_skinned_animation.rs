//! Skinned models are posed at the frame's time (issue 28): Fox (tests/data), skinned and
//! animated, rendered over three frames. Under the glTF animation (`--motion auto`, a placed
//! camera kept where it was put) the depth the G-buffer sees differs between the frames at
//! t = 0 and t = 1.71 s, and render.json says the geometry was animated and what posing cost;
//! under `--motion none` every frame shows the pose of t = 0, depth identical bit for bit. On
//! lavapipe, one 24×24 view.

mod common;

use std::path::Path;

use common::{parallax_in, scratch};

const FOX: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/fox/Fox.gltf");

/// Renders Fox's three frames (t = 0, 1.71, 3.42 s under the animation) into `out`, the first
/// two also into frame_00000/ and frame_00001/, with the depth layer; returns render.json.
fn render_fox(dir: &Path, out: &str, motion: &[&str]) -> serde_json::Value {
    let args = [
        &["render", "--scene", FOX, "--lf", "1x1", "--resolution", "24x24", "--fake-devices", "1"][..],
        &["--camera", "0,40,250,0,40,0,0,1,0,40", "--frames", "3", "--warmup", "0", "--save-every", "1"],
        &["--layers", "--out-dir", out],
        motion,
    ]
    .concat();
    let run = parallax_in(dir, &args);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    serde_json::from_slice(&std::fs::read(dir.join(out).join("render.json")).unwrap()).unwrap()
}

/// The G-buffer depth of the view (first hits, no jitter: the same geometry gives the same
/// depth in every frame).
fn depth(exr: &Path) -> Vec<f32> {
    let (_, _, mut channels) = parallax_scene::output::read_exr_channels(exr, &["depth.Z"]).unwrap();
    channels.remove(0)
}

#[test]
fn a_skinned_model_moves_with_its_animation_and_holds_still_under_motion_none() {
    let dir = scratch("skinned", "fox");
    let report = render_fox(&dir, "animated", &[]);
    assert_eq!(report["motion"], "animation", "auto runs the meshes' animation under a placed camera");
    assert_eq!(report["setup"]["still"], false, "compare refuses a moving run against a still reference");
    let geometry = &report["geometry"];
    assert_eq!(geometry["animated"], true, "{geometry}");
    assert_eq!(geometry["posed_frames"], 2, "frames 1 and 2; frame 0 shows the pose it was loaded in");
    for figure in ["pose", "bvh", "upload", "total"] {
        assert!(geometry[figure]["mean_ms"].as_f64().is_some_and(|ms| ms > 0.0), "{figure}: {geometry}");
    }
    let animated = dir.join("animated");
    let (start, later) =
        (depth(&animated.join("frame_00000/view_000.exr")), depth(&animated.join("frame_00001/view_000.exr")));
    let moved = start.iter().zip(&later).filter(|(a, b)| a != b).count();
    assert!(moved >= 10, "t = 0 and t = 1.71 s see the fox in other poses: {moved} of 576 pixels differ");

    let report = render_fox(&dir, "still", &["--motion", "none"]);
    assert_eq!(report["motion"], "none");
    assert_eq!(report["geometry"]["animated"], false);
    assert_eq!(report["geometry"]["posed_frames"], 0);
    let still = dir.join("still");
    let first = depth(&still.join("frame_00000/view_000.exr"));
    assert_eq!(first, start, "--motion none shows the pose of t = 0, the animation's first frame");
    assert_eq!(depth(&still.join("frame_00001/view_000.exr")), first);
    assert_eq!(depth(&still.join("view_000.exr")), first);
}
