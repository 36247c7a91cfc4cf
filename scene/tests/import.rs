//! glTF import: the committed test scenes, and every class of bad input giving its own error.

use std::path::{Path, PathBuf};

use glam::Vec3;
use parallax_scene::{AlphaMode, SceneError, load_gltf, load_gltf_bytes};

fn data(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data").join(rel)
}

const CORNELL: &str = "cornell_box/CornellBox-Original.gltf";
const FOX: &str = "fox/Fox.gltf";

/// A fresh, empty directory for one test, removed again when the test is done with it.
struct ScratchDir(PathBuf);

impl std::ops::Deref for ScratchDir {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn scratch_dir(name: &str) -> ScratchDir {
    let d = std::env::temp_dir().join(format!("parallax-scene-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    ScratchDir(d)
}

#[test]
fn cornell_box_imports_with_materials_light_and_camera() {
    let s = load_gltf(data(CORNELL)).unwrap();
    assert_eq!(s.triangle_count(), 36);
    assert_eq!(s.materials.len(), 8);
    assert!(s.textures.is_empty());
    s.check().unwrap();
    // The light: emissiveFactor (1, 0.706, 0.235) x KHR_materials_emissive_strength 17.
    let light = s.materials.iter().find(|m| m.is_emissive()).expect("an emissive material");
    assert!((light.emissive - Vec3::new(17.0, 12.0, 4.0)).abs().max_element() < 0.02, "{}", light.emissive);
    let red = s.materials.iter().find(|m| m.base_color.x > 0.6 && m.base_color.y < 0.1).unwrap();
    assert_eq!((red.metallic, red.roughness), (0.0, 1.0));
    // The camera node: yfov 0.686 at (0, 0.983, 3.87) looking down -Z.
    assert_eq!(s.cameras.len(), 1);
    let c = s.cameras[0];
    assert!((c.yfov - 0.686).abs() < 1e-3);
    assert!((c.eye - Vec3::new(0.0, 0.9828, 3.87)).length() < 1e-4);
    assert!((c.forward - Vec3::NEG_Z).length() < 1e-6);
    let b = s.bounds();
    assert!((b.min - Vec3::new(-1.02, 0.0, -1.04)).abs().max_element() < 0.01, "{:?}", b);
    assert!((b.max - Vec3::new(1.0, 1.99, 0.99)).abs().max_element() < 0.01, "{:?}", b);
    for n in &s.normals {
        assert!((n.length() - 1.0).abs() < 1e-4);
    }
}

#[test]
fn fox_without_indices_or_normals_gets_flat_normals_and_its_texture() {
    let s = load_gltf(data(FOX)).unwrap();
    assert_eq!(s.triangle_count(), 576);
    assert_eq!(s.positions.len(), 1728);
    s.check().unwrap();
    assert_eq!(s.textures.len(), 1);
    let t = &s.textures[0];
    assert!(t.width > 0 && t.height > 0);
    assert_eq!(t.rgba8.len(), (4 * t.width * t.height) as usize);
    assert_eq!(s.materials[0].base_color_texture, Some(0));
    // Flat normals: unit, perpendicular to their triangle, same for all three corners.
    let mut flat = 0;
    for (k, tri) in s.triangles.iter().enumerate() {
        let [a, b, c] = s.triangle_positions(k);
        let face = (b - a).cross(c - a);
        if face.length() < 1e-6 {
            continue;
        }
        let n = s.normals[tri[0] as usize];
        assert_eq!(n, s.normals[tri[1] as usize]);
        assert_eq!(n, s.normals[tri[2] as usize]);
        assert!(n.dot(face.normalize()) > 0.9999, "triangle {k}");
        flat += 1;
    }
    assert!(flat > 500);
    // Skinned at t = 0 of its first animation (Survey), the fox stands about 79 units tall on
    // y = 0, as in its rest pose.
    let b = s.bounds();
    assert!((b.max.y - b.min.y - 79.0).abs() < 5.0, "{:?}", b);
}

fn cornell_json() -> serde_like::Json {
    serde_like::Json(std::fs::read_to_string(data(CORNELL)).unwrap())
}

/// Tiny textual edits of the Cornell JSON, so tests need no JSON library.
mod serde_like {
    pub struct Json(pub String);
    impl Json {
        pub fn replace(mut self, from: &str, to: &str) -> Self {
            assert!(self.0.contains(from), "test edit target '{from}' missing");
            self.0 = self.0.replacen(from, to, 1);
            self
        }
    }
}

#[test]
fn missing_buffer_is_named() {
    let dir = scratch_dir("missing-buffer");
    let p = dir.join("box.gltf");
    std::fs::write(&p, cornell_json().0).unwrap(); // without the .bin next to it
    match load_gltf(&p) {
        Err(SceneError::MissingBuffer { path, buffer, uri, .. }) => {
            assert_eq!(path, p);
            assert_eq!(buffer, 0);
            assert_eq!(uri, "CornellBox-Original.bin");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn short_buffer_is_a_missing_buffer() {
    let dir = scratch_dir("short-buffer");
    let p = dir.join("box.gltf");
    std::fs::write(&p, cornell_json().0).unwrap();
    let bin = std::fs::read(data("cornell_box/CornellBox-Original.bin")).unwrap();
    std::fs::write(dir.join("CornellBox-Original.bin"), &bin[..bin.len() / 2]).unwrap();
    assert!(matches!(load_gltf(&p), Err(SceneError::MissingBuffer { buffer: 0, .. })));
}

#[test]
fn malformed_json_is_reported() {
    let base = data("cornell_box");
    let json = cornell_json().0;
    let p = Path::new("broken.gltf");
    let err = load_gltf_bytes(&json.as_bytes()[..json.len() / 3], &base, p).unwrap_err();
    assert!(matches!(err, SceneError::MalformedJson { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.starts_with("broken.gltf: malformed glTF JSON"), "{msg}");
}

#[test]
fn unsupported_required_extension_is_named() {
    let json = cornell_json().replace(
        "\"extensionsUsed\": [",
        "\"extensionsRequired\": [\"KHR_draco_mesh_compression\"],\n \"extensionsUsed\": [\"KHR_draco_mesh_compression\",",
    );
    let err = load_gltf_bytes(json.0.as_bytes(), &data("cornell_box"), Path::new("draco.gltf")).unwrap_err();
    match &err {
        SceneError::UnsupportedExtension { extension, .. } => {
            assert_eq!(extension, "KHR_draco_mesh_compression")
        }
        other => panic!("{other:?}"),
    }
    assert!(err.to_string().contains("KHR_draco_mesh_compression"));
}

#[test]
fn supported_required_extension_loads() {
    let json = cornell_json().replace(
        "\"extensionsUsed\": [",
        "\"extensionsRequired\": [\"KHR_materials_emissive_strength\"],\n \"extensionsUsed\": [",
    );
    let s = load_gltf_bytes(json.0.as_bytes(), &data("cornell_box"), Path::new("x.gltf")).unwrap();
    assert_eq!(s.triangle_count(), 36);
}

/// A one-triangle glTF with the given u32 indices and an external .bin.
fn write_triangle_gltf(dir: &Path, indices: &[u32]) -> PathBuf {
    let mut bin = Vec::new();
    for v in [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in v {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in indices {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    std::fs::write(dir.join("tri.bin"), &bin).unwrap();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "buffers":[{{"uri":"tri.bin","byteLength":{len}}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":{il}}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
                     {{"bufferView":1,"componentType":5125,"count":{ic},"type":"SCALAR"}}]}}"#,
        len = bin.len(),
        il = 4 * indices.len(),
        ic = indices.len()
    );
    let p = dir.join("tri.gltf");
    std::fs::write(&p, json).unwrap();
    p
}

#[test]
fn hand_written_triangle_loads() {
    let dir = scratch_dir("good-triangle");
    let s = load_gltf(write_triangle_gltf(&dir, &[0, 1, 2])).unwrap();
    assert_eq!(s.triangle_count(), 1);
    // Default material (none given): glTF's white metal.
    assert_eq!(s.materials.len(), 1);
    assert_eq!(s.materials[0].alpha_mode, AlphaMode::Opaque);
    assert!((s.normals[0] - Vec3::Z).length() < 1e-6, "generated flat normal");
}

#[test]
fn absurd_index_is_reported_with_its_value() {
    let dir = scratch_dir("absurd-index");
    let p = write_triangle_gltf(&dir, &[0, 1, 4_000_000_000]);
    match load_gltf(&p) {
        Err(SceneError::IndexOutOfRange { index, vertex_count, mesh, primitive, .. }) => {
            assert_eq!((index, vertex_count, mesh, primitive), (4_000_000_000, 3, 0, 0));
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn accessor_past_its_view_is_reported() {
    let dir = scratch_dir("accessor-oob");
    let p = write_triangle_gltf(&dir, &[0, 1, 2]);
    let json = std::fs::read_to_string(&p)
        .unwrap()
        .replace("\"count\":3,\"type\":\"SCALAR\"", "\"count\":3000,\"type\":\"SCALAR\"");
    std::fs::write(&p, json).unwrap();
    assert!(matches!(load_gltf(&p), Err(SceneError::AccessorOutOfBounds { accessor: 1, .. })));
}

#[test]
fn missing_file_is_io_error_with_path() {
    let p = data("no/such/scene.gltf");
    match load_gltf(&p) {
        Err(SceneError::Io { path, .. }) => assert_eq!(path, p),
        other => panic!("{other:?}"),
    }
}

/// xorshift for reproducible corruption.
fn next(state: &mut u64) -> u64 {
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    *state
}

/// Truncations and byte flips of both the JSON and the binary buffer: every outcome is Ok or a
/// SceneError, never a panic (the loader's panic backstop would turn one into "internal panic
/// caught", which this test also rejects).
#[test]
fn fuzzed_files_never_panic() {
    let dir = scratch_dir("fuzz");
    let json = std::fs::read(data(CORNELL)).unwrap();
    let bin = std::fs::read(data("cornell_box/CornellBox-Original.bin")).unwrap();
    let gltf_path = dir.join("f.gltf");
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut outcomes = [0usize; 2];
    let mut check = |r: Result<parallax_scene::Scene, SceneError>| match r {
        Ok(s) => {
            s.check().unwrap();
            outcomes[0] += 1;
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.contains("internal panic"), "{msg}");
            outcomes[1] += 1;
        }
    };
    // Truncated JSON at many lengths.
    for k in 0..60 {
        let cut = json.len() * k / 60;
        check(load_gltf_bytes(&json[..cut], &data("cornell_box"), &gltf_path));
    }
    // Random byte flips in the JSON (digits and structure alike).
    for _ in 0..5000 {
        let mut j = json.clone();
        for _ in 0..1 + next(&mut state) % 4 {
            let i = (next(&mut state) % j.len() as u64) as usize;
            j[i] = (next(&mut state) % 128) as u8;
        }
        check(load_gltf_bytes(&j, &data("cornell_box"), &gltf_path));
    }
    // Random digit changes: keeps the JSON valid but bends counts, offsets and indices.
    let digits: Vec<usize> = json.iter().enumerate().filter(|(_, c)| c.is_ascii_digit()).map(|(i, _)| i).collect();
    for _ in 0..5000 {
        let mut j = json.clone();
        let i = digits[(next(&mut state) % digits.len() as u64) as usize];
        j[i] = b'0' + (next(&mut state) % 10) as u8;
        check(load_gltf_bytes(&j, &data("cornell_box"), &gltf_path));
    }
    // Corrupted and truncated binary buffers.
    std::fs::write(&gltf_path, &json).unwrap();
    for round in 0..500 {
        let mut b = bin.clone();
        if round % 4 == 0 {
            b.truncate((next(&mut state) % b.len() as u64) as usize);
        } else {
            for _ in 0..8 {
                let i = (next(&mut state) % b.len() as u64) as usize;
                b[i] = next(&mut state) as u8;
            }
        }
        std::fs::write(dir.join("CornellBox-Original.bin"), &b).unwrap();
        check(load_gltf(&gltf_path));
    }
    assert!(outcomes[0] > 0 && outcomes[1] > 0, "both outcomes should occur: {outcomes:?}");
}

/// KHR_lights_punctual (point and spot under rotated/translated nodes) and a perspective camera
/// on a child node: world-space positions and directions come from the node hierarchy.
#[test]
fn punctual_lights_and_cameras_follow_node_transforms() {
    let dir = scratch_dir("lights");
    let tri = write_triangle_gltf(&dir, &[0, 1, 2]);
    let json = std::fs::read_to_string(&tri).unwrap();
    // Rotation of -90 degrees about X turns the node's -Z (where lights shine) into -Y.
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let json = json
        .replace(
            r#""nodes":[{"mesh":0}]"#,
            &format!(
                r#""nodes":[{{"mesh":0,"children":[1,2]}},
                   {{"translation":[1,4,2],"rotation":[{n},0,0,{s}],"extensions":{{"KHR_lights_punctual":{{"light":0}}}}}},
                   {{"translation":[0,1,5],"children":[3]}},
                   {{"translation":[0,0,1],"camera":0}}],
                   "cameras":[{{"type":"perspective","perspective":{{"yfov":0.8,"znear":0.1}}}}],
                   "extensionsUsed":["KHR_lights_punctual"],
                   "extensions":{{"KHR_lights_punctual":{{"lights":[
                     {{"type":"spot","color":[1,0.5,0.25],"intensity":40,"spot":{{"innerConeAngle":0.2,"outerConeAngle":0.5}}}}]}}}}"#,
                n = -s
            ),
        );
    std::fs::write(&tri, json).unwrap();
    let scene = load_gltf(&tri).unwrap();
    assert_eq!(scene.lights.len(), 1);
    let l = &scene.lights[0];
    assert_eq!(l.kind, parallax_scene::PunctualKind::Spot { inner_cone: 0.2, outer_cone: 0.5 });
    assert!((l.position - Vec3::new(1.0, 4.0, 2.0)).length() < 1e-5, "{}", l.position);
    assert!((l.direction - Vec3::NEG_Y).length() < 1e-5, "{}", l.direction);
    assert_eq!((l.color, l.intensity), (Vec3::new(1.0, 0.5, 0.25), 40.0));
    assert_eq!(scene.cameras.len(), 1);
    let c = scene.cameras[0];
    assert!((c.eye - Vec3::new(0.0, 1.0, 6.0)).length() < 1e-5, "{}", c.eye);
    assert!((c.forward - Vec3::NEG_Z).length() < 1e-6);
    assert!((c.yfov - 0.8).abs() < 1e-6);
}

/// The triangle of `write_triangle_gltf` under other `nodes` (and extra root members).
fn triangle_with_nodes(dir: &Path, nodes: &str, extra: &str) -> Result<parallax_scene::Scene, SceneError> {
    let path = write_triangle_gltf(dir, &[0, 1, 2]);
    let json = std::fs::read_to_string(&path).unwrap().replacen(r#""nodes":[{"mesh":0}]"#, nodes, 1);
    let json = format!("{}{extra}}}", json.trim_end().strip_suffix('}').unwrap());
    load_gltf_bytes(json.as_bytes(), dir, &path)
}

#[test]
fn coordinates_beyond_the_f32_safe_range_are_refused_before_the_bvh() {
    let dir = scratch_dir("far");
    let far = triangle_with_nodes(&dir, r#""nodes":[{"mesh":0,"translation":[1e20,0,0]}]"#, "");
    match far {
        Err(SceneError::CoordinateOutOfRange { what, value, limit, .. }) => {
            assert_eq!(what, "vertex 0 of accessor 0 (node 0, mesh 0 primitive 0) in world space");
            assert_eq!((value, limit), (1e20, 1e18));
        }
        other => panic!("{other:?}"),
    }
    // Large but within range (a translation of 1e17 would round the triangle away to zero area).
    assert!(triangle_with_nodes(&dir, r#""nodes":[{"mesh":0,"scale":[1e17,1e17,1e17]}]"#, "").is_ok());
}

#[test]
fn a_scene_of_zero_area_names_the_flattening_node() {
    let dir = scratch_dir("flat");
    let flat = triangle_with_nodes(&dir, r#""nodes":[{"mesh":0,"scale":[1,0,1]}]"#, "");
    match flat {
        Err(SceneError::ZeroArea { hint, .. }) => assert_eq!(hint, "node 0 has a transform of zero scale"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn cameras_outside_the_spec_are_refused() {
    let dir = scratch_dir("cameras");
    let nodes = r#""nodes":[{"mesh":0,"children":[1]},{"camera":0,"translation":[0,0,3]}]"#;
    for yfov in ["0", "4", "3.2"] {
        let cameras = format!(r#","cameras":[{{"type":"perspective","perspective":{{"yfov":{yfov},"znear":0.1}}}}]"#);
        match triangle_with_nodes(&dir, nodes, &cameras) {
            Err(SceneError::BadCamera { camera: 0, node: 1, detail, .. }) => {
                assert_eq!(detail, format!("yfov {yfov} rad is outside 0 < yfov < π (glTF spec); use e.g. 0.8"))
            }
            other => panic!("yfov {yfov}: {other:?}"),
        }
    }
    let cameras = r#","cameras":[{"type":"perspective","perspective":{"yfov":0.8,"znear":0.1}}]"#;
    let flat_camera = nodes.replace(r#""translation":[0,0,3]"#, r#""scale":[0,0,0]"#);
    assert!(matches!(triangle_with_nodes(&dir, &flat_camera, cameras), Err(SceneError::BadCamera { node: 1, .. })));
    assert_eq!(triangle_with_nodes(&dir, nodes, cameras).unwrap().cameras.len(), 1);
}

#[test]
fn files_that_are_not_gltf_are_named_as_such() {
    let dir = scratch_dir("not-gltf");
    let obj = load_gltf_bytes(b"v 0 0 0\nf 1 1 1\n", &dir, Path::new("cube.obj"));
    assert!(
        matches!(&obj, Err(SceneError::NotGltf { detail, .. }) if detail == "the file is neither JSON nor binary glTF")
    );
    let glb = load_gltf_bytes(b"{\"asset\":{}}", &dir, Path::new("x.glb"));
    assert!(matches!(&glb, Err(SceneError::NotGltf { detail, .. }) if detail.contains("magic `glTF`")), "{glb:?}");
    let empty = load_gltf_bytes(b"  \n", &dir, Path::new("x.gltf"));
    assert!(matches!(&empty, Err(SceneError::NotGltf { detail, .. }) if detail == "the file is empty"));
}

/// What the gltf crate's `Image::source` would unwrap (a panic) is refused first, naming the
/// image and what the spec requires.
#[test]
fn malformed_images_are_named_before_the_gltf_crate_sees_them() {
    let dir = scratch_dir("malformed-images");
    let p = write_triangle_gltf(&dir, &[0, 1, 2]);
    let base = std::fs::read_to_string(&p).unwrap();
    let cases = [
        (r#"[{"name":"a"}]"#, 0, "has neither uri nor bufferView"),
        (
            r#"[{"uri":"a.png"},{"uri":"b.png","bufferView":0,"mimeType":"image/png"}]"#,
            1,
            "has both uri and bufferView",
        ),
        (r#"[{"bufferView":0}]"#, 0, "has a bufferView but no mimeType"),
        (r#"[{"bufferView":7,"mimeType":"image/png"}]"#, 0, "names bufferView 7 of 2"),
    ];
    for (images, index, needle) in cases {
        let json = base.replacen(r#""buffers""#, &format!(r#""images":{images},"buffers""#), 1);
        let err = load_gltf_bytes(json.as_bytes(), &dir, &p).unwrap_err();
        match &err {
            SceneError::MalformedImage { path, image, detail } => {
                assert_eq!((path.as_path(), *image), (p.as_path(), index), "{images}");
                assert!(detail.contains(needle), "{images}: {detail}");
            }
            other => panic!("{images}: {other:?}"),
        }
        assert!(!err.to_string().contains("panic"), "{err}");
    }
}

/// Image entries that name one file are one texture, decoded once, and the file is listed once
/// among the scene's sources (issue 30: eight entries naming one large PNG decoded it eight
/// times).
#[test]
fn image_entries_naming_one_file_share_one_texture() {
    let dir = scratch_dir("shared-images");
    std::fs::copy(data("fox/Texture.png"), dir.join("t.png")).unwrap();
    let extra = r#","images":[{"uri":"t.png"},{"uri":"t.png"},{"uri":"t.png"}],"textures":[{"source":0},{"source":2}],
"materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}},{"emissiveTexture":{"index":1}}]"#;
    let s = triangle_with_nodes(&dir, r#""nodes":[{"mesh":0}]"#, extra).unwrap();
    assert_eq!(s.textures.len(), 1);
    assert_eq!(s.materials[0].base_color_texture, Some(0));
    assert_eq!(s.materials[1].emissive_texture, Some(0));
    assert_eq!(s.sources.iter().filter(|f| f.name == "t.png").count(), 1);
}
