//! A glTF camera animation is read on import: the camera node's translation keyframes, under a
//! rotated parent, give the camera of any time (held at the ends); a malformed channel is refused
//! naming the animation.

use std::path::Path;

use glam::Vec3;
use parallax_scene::load_gltf_bytes;

/// Little-endian bytes of `floats`, in the data URI a .gltf embeds.
fn data_uri(floats: &[f32]) -> String {
    const TABLE: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let bytes: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    let mut out = String::from("data:application/octet-stream;base64,");
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(TABLE[((n >> (18 - 6 * i)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// One triangle; a parent node turned a quarter about y holding the camera node, whose
/// translation goes from (0,0,0) at t = 0 to (0,0,10) at t = 2 (`times`, `translations`).
fn gltf(times: &[f32], translations: &[f32]) -> String {
    let triangle = [0.0f32, 0.0, -5.0, 1.0, 0.0, -5.0, 0.0, 1.0, -5.0];
    let mut data = triangle.to_vec();
    data.extend_from_slice(times);
    data.extend_from_slice(translations);
    let (t_off, v_off) = (36, 36 + 4 * times.len());
    let q = std::f32::consts::FRAC_1_SQRT_2;
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]}}],
  "nodes":[{{"mesh":0}},{{"rotation":[0,{q},0,{q}],"children":[2]}},{{"camera":0}}],
  "cameras":[{{"type":"perspective","perspective":{{"yfov":0.8,"znear":0.01}}}}],
  "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
  "animations":[{{"channels":[{{"sampler":0,"target":{{"node":2,"path":"translation"}}}}],
                  "samplers":[{{"input":1,"output":2,"interpolation":"LINEAR"}}]}}],
  "buffers":[{{"byteLength":{len},"uri":"{uri}"}}],
  "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},
                 {{"buffer":0,"byteOffset":{t_off},"byteLength":{t_len}}},
                 {{"buffer":0,"byteOffset":{v_off},"byteLength":{v_len}}}],
  "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,-5],"max":[1,1,-5]}},
               {{"bufferView":1,"componentType":5126,"count":{n},"type":"SCALAR","min":[{tmin}],"max":[{tmax}]}},
               {{"bufferView":2,"componentType":5126,"count":{m},"type":"VEC3"}}]}}"#,
        len = 4 * data.len(),
        uri = data_uri(&data),
        t_len = 4 * times.len(),
        v_len = 4 * translations.len(),
        n = times.len(),
        m = translations.len() / 3,
        tmin = times.iter().cloned().fold(f32::MAX, f32::min),
        tmax = times.iter().cloned().fold(f32::MIN, f32::max),
    )
}

#[test]
fn the_camera_follows_its_node_and_its_parents() {
    let text = gltf(&[0.0, 2.0], &[0.0, 0.0, 0.0, 0.0, 0.0, 10.0]);
    let scene = load_gltf_bytes(text.as_bytes(), Path::new("."), Path::new("animated.gltf")).unwrap();
    let animation = scene.camera_animation.expect("the camera node is animated");
    assert_eq!(animation.duration, 2.0);
    // The parent turns +z into +x: half way the camera sits at x = 5 and looks along -x.
    let camera = animation.camera_at(1.0);
    assert!((camera.eye - Vec3::new(5.0, 0.0, 0.0)).length() < 1e-5, "{}", camera.eye);
    assert!((camera.forward - Vec3::NEG_X).length() < 1e-5, "{}", camera.forward);
    assert!((animation.camera_at(9.0).eye - Vec3::new(10.0, 0.0, 0.0)).length() < 1e-5);
    // The scene's camera is the rest pose.
    assert!(scene.cameras[0].eye.length() < 1e-6);
}

#[test]
fn a_still_scene_has_no_animation() {
    let scene = parallax_scene::default_scene();
    assert!(scene.camera_animation.is_none());
}

#[test]
fn keyframes_out_of_order_are_refused_naming_the_channel() {
    let text = gltf(&[2.0, 0.0], &[0.0, 0.0, 0.0, 0.0, 0.0, 10.0]);
    let err = load_gltf_bytes(text.as_bytes(), Path::new("."), Path::new("bad.gltf")).err().unwrap();
    let message = err.to_string();
    assert!(
        message.contains("animation 0 sampler 0 (channel 0, node 2)") && message.contains("increasing"),
        "{message}"
    );
}

/// NaN, infinity or 1e30 in a camera path used to render black frames while render.json
/// reported a moving camera; such a path is refused naming the sampler and the value.
#[test]
fn non_finite_or_huge_keyframes_are_refused_naming_the_sampler() {
    for (times, translations, needle) in [
        ([0.0, 2.0], [0.0, 0.0, 0.0, 0.0, f32::NAN, 10.0], "translation keyframe value 1"),
        ([0.0, 2.0], [0.0, 0.0, 0.0, 0.0, 0.0, f32::INFINITY], "translation keyframe value 1"),
        ([0.0, 2.0], [1e30, 0.0, 0.0, 0.0, 0.0, 10.0], "translation keyframe value 0"),
        ([0.0, 1e30], [0.0, 0.0, 0.0, 0.0, 0.0, 10.0], "keyframe time 1e30 s is outside 0..=1e6 s"),
    ] {
        let text = gltf(&times, &translations);
        let err = load_gltf_bytes(text.as_bytes(), Path::new("."), Path::new("bad.gltf")).err().unwrap();
        let message = err.to_string();
        assert!(message.contains("bad.gltf: invalid glTF: animation 0 sampler 0"), "{message}");
        assert!(message.contains(needle), "{needle}: {message}");
    }
}
