//! Skinned and node-animated meshes are posed at a time of the file's animation: a hand-built
//! skeleton of two joints (a root that slides along -z, an arm turning about z) skins one
//! triangle and carries an unskinned one; the posed vertices are checked against positions
//! worked out here with plain trigonometry. Fox, in tests/data, moves between two times of its
//! first animation (Survey) and keeps flat normals.

use std::f32::consts::FRAC_1_SQRT_2;
use std::path::{Path, PathBuf};

use glam::Vec3;
use parallax_scene::{Scene, SceneError, load_gltf};

/// The skeleton: node 0 holds mesh 0 skinned by skin 0 (joints 1 and 2); node 1 (root joint)
/// slides from z = 0 at t = 0 to z = -4 at t = 2 while its scale goes from 1 to `root_scale`;
/// node 2 (arm joint, child of 1, at x = 1)
/// turns from 0 to 90° about +z over the same time; node 3, a child of the arm at y = 1,
/// holds mesh 1: the same triangle without skin or normals (flat shaded). Triangle corners
/// (0,0,0) on the root, (2,0,0) on the arm, (2,1,0) half on each; their normals +z, +x, +z.
fn skeleton_gltf(dir: &Path, root_scale: f32) -> PathBuf {
    let floats: Vec<f32> = [
        // 0: positions, 3 × VEC3
        &[0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 2.0, 1.0, 0.0][..],
        // 36: normals
        &[0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        // 72: weights, 3 × VEC4, of the joints below
        &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0],
        // 120: inverse bind matrices (column-major): identity for the root, x - 1 for the arm
        &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        &[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 1.0],
        // 248: key times
        &[0.0, 2.0],
        // 256: root translations
        &[0.0, 0.0, 0.0, 0.0, 0.0, -4.0],
        // 280: arm rotations (x, y, z, w): none, then a quarter turn about z
        &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, FRAC_1_SQRT_2, FRAC_1_SQRT_2],
        // 312: root scales
        &[1.0, 1.0, 1.0, root_scale, root_scale, root_scale],
    ]
    .concat();
    let mut bytes: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    // 336: joints, 3 × VEC4 of u8 (the root is skin joint 0, the arm joint 1): the first
    // vertex on the root, the second on the arm, the third on both.
    bytes.extend_from_slice(&[0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0]);
    std::fs::write(dir.join("skeleton.bin"), &bytes).unwrap();
    let gltf = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0,1]}}],
  "nodes":[{{"mesh":0,"skin":0}},{{"children":[2]}},{{"translation":[1,0,0],"children":[3]}},
           {{"translation":[0,1,0],"mesh":1}}],
  "skins":[{{"joints":[1,2],"inverseBindMatrices":3}}],
  "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1,"WEIGHTS_0":2,"JOINTS_0":8}}}}]}},
            {{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
  "animations":[{{"channels":[{{"sampler":0,"target":{{"node":1,"path":"translation"}}}},
                              {{"sampler":1,"target":{{"node":2,"path":"rotation"}}}},
                              {{"sampler":2,"target":{{"node":1,"path":"scale"}}}}],
                  "samplers":[{{"input":4,"output":5,"interpolation":"LINEAR"}},
                              {{"input":4,"output":6,"interpolation":"LINEAR"}},
                              {{"input":4,"output":7,"interpolation":"LINEAR"}}]}}],
  "buffers":[{{"byteLength":{len},"uri":"skeleton.bin"}}],
  "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":36}},
                 {{"buffer":0,"byteOffset":72,"byteLength":48}},{{"buffer":0,"byteOffset":120,"byteLength":128}},
                 {{"buffer":0,"byteOffset":248,"byteLength":8}},{{"buffer":0,"byteOffset":256,"byteLength":24}},
                 {{"buffer":0,"byteOffset":280,"byteLength":32}},{{"buffer":0,"byteOffset":312,"byteLength":24}},
                 {{"buffer":0,"byteOffset":336,"byteLength":12}}],
  "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[2,1,0]}},
               {{"bufferView":1,"componentType":5126,"count":3,"type":"VEC3"}},
               {{"bufferView":2,"componentType":5126,"count":3,"type":"VEC4"}},
               {{"bufferView":3,"componentType":5126,"count":2,"type":"MAT4"}},
               {{"bufferView":4,"componentType":5126,"count":2,"type":"SCALAR","min":[0],"max":[2]}},
               {{"bufferView":5,"componentType":5126,"count":2,"type":"VEC3"}},
               {{"bufferView":6,"componentType":5126,"count":2,"type":"VEC4"}},
               {{"bufferView":7,"componentType":5126,"count":2,"type":"VEC3"}},
               {{"bufferView":8,"componentType":5121,"count":3,"type":"VEC4"}}]}}"#,
        len = bytes.len()
    );
    let path = dir.join("skeleton.gltf");
    std::fs::write(&path, gltf).unwrap();
    path
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).length() < 1e-5
}

fn positions(scene: &Scene) -> [Vec3; 6] {
    std::array::from_fn(|k| scene.positions[k])
}

#[test]
fn a_skinned_vertex_follows_its_joints_at_the_frame_time() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = load_gltf(skeleton_gltf(dir.path(), 1.0)).unwrap();
    assert!(scene.geometry_moves());
    assert_eq!(scene.geometry_animation.as_ref().unwrap().duration(), 2.0);
    // Mesh 0 keeps its three vertices (it has normals); mesh 1 gets one per corner (flat).
    assert_eq!(scene.positions.len(), 6);

    // t = 0, as loaded: the bind pose (no slide, no turn); mesh 1 in the frame of node 3, one
    // unit along x (the arm) and one up.
    let rest = [Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0), Vec3::new(2.0, 1.0, 0.0)];
    let loaded = positions(&scene);
    assert_eq!(loaded[..3], rest);
    for (k, p) in rest.iter().enumerate() {
        assert!(close(loaded[3 + k], *p + Vec3::new(1.0, 1.0, 0.0)), "mesh 1 vertex {k}: {}", loaded[3 + k]);
    }

    // t = 1: the root has slid to z = -2 and the arm turned 45°. Worked out by hand: a point
    // (x, y) of the arm's frame is at (1 + c·x - s·y, s·x + c·y, -2) with c = s = cos 45°.
    scene.pose_at(1.0).unwrap();
    let (c, s) = (FRAC_1_SQRT_2, FRAC_1_SQRT_2);
    let arm = |x: f32, y: f32| Vec3::new(1.0 + c * x - s * y, s * x + c * y, -2.0);
    let root = |p: Vec3| p + Vec3::new(0.0, 0.0, -2.0);
    let posed = positions(&scene);
    let expected = [
        root(Vec3::ZERO),
        // (2, 0, 0) bound to the arm: 1 along the arm's x.
        arm(1.0, 0.0),
        // (2, 1, 0) half on the root, half on the arm (1 along x, 1 along y).
        0.5 * root(Vec3::new(2.0, 1.0, 0.0)) + 0.5 * arm(1.0, 1.0),
        // Mesh 1: the file's triangle one unit up in the arm's frame.
        arm(0.0, 1.0),
        arm(2.0, 1.0),
        arm(2.0, 2.0),
    ];
    for (k, (p, e)) in posed.iter().zip(&expected).enumerate() {
        assert!(close(*p, *e), "vertex {k} at t = 1: {p}, expected {e}");
    }
    // The arm's vertex normal (+x) turns with it; the others stay +z.
    assert!(close(scene.normals[1], Vec3::new(c, s, 0.0)), "{}", scene.normals[1]);
    assert!(close(scene.normals[0], Vec3::Z));
    // Mesh 1 is flat shaded: its face normal is recomputed for the pose, still +z (a turn about z).
    assert!((3..6).all(|k| close(scene.normals[k], Vec3::Z)));

    // After the last keyframe the last pose holds: slid to z = -4, a quarter turn.
    scene.pose_at(7.0).unwrap();
    assert!(close(scene.positions[1], Vec3::new(1.0, 1.0, -4.0)), "{}", scene.positions[1]);
    // And posing at 0 again gives the loaded pose back.
    scene.pose_at(0.0).unwrap();
    assert_eq!(positions(&scene), loaded);
}

/// A pose that throws a vertex beyond the coordinate range the BVH takes is an error naming the
/// vertex and the time, not a panic in the BVH builder: every keyframe is within range, but a
/// root scale of 6e17 puts mesh 1's second vertex, two units up in the turned arm's frame, at
/// y = 1.2e18 (mesh 0 stays within 6e17).
#[test]
fn a_pose_beyond_the_coordinate_range_is_refused_naming_the_time() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = load_gltf(skeleton_gltf(dir.path(), 6e17)).unwrap();
    let err = scene.pose_at(2.0).unwrap_err();
    assert!(matches!(err, SceneError::CoordinateOutOfRange { .. }), "{err:?}");
    let message = err.to_string();
    assert!(
        message.contains("vertex 1 of mesh 1 primitive 0, posed by the animation at t = 2 s has a coordinate of 1.2"),
        "{message}"
    );
}

#[test]
fn a_scene_without_animation_or_with_a_camera_animation_only_is_still() {
    assert!(!parallax_scene::default_scene().geometry_moves());
    let cornell = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/cornell_box/CornellBox-Original.gltf");
    assert!(!load_gltf(cornell).unwrap().geometry_moves());
}

/// Fox's first animation (Survey) moves its joints: its vertices differ between two times, the
/// flat normals still face their triangles, and posing back gives the loaded pose.
#[test]
fn fox_moves_with_its_first_animation() {
    let fox = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/data/fox/Fox.gltf");
    let mut scene = load_gltf(fox).unwrap();
    let animation = scene.geometry_animation.as_ref().expect("Fox is skinned and animated");
    assert!((animation.duration() - 3.4166667).abs() < 1e-5, "Survey lasts 3.42 s");
    let loaded = scene.positions.clone();
    scene.pose_at(1.5).unwrap();
    let moved = scene.positions.iter().zip(&loaded).filter(|(a, b)| (**a - **b).length() > 0.1).count();
    assert!(moved > 100, "{moved} of {} vertices moved", loaded.len());
    for (k, tri) in scene.triangles.iter().enumerate() {
        let [a, b, c] = scene.triangle_positions(k);
        let face = (b - a).cross(c - a);
        if face.length() > 1e-6 {
            assert!(scene.normals[tri[0] as usize].dot(face.normalize()) > 0.9999, "triangle {k}");
        }
    }
    scene.pose_at(0.0).unwrap();
    assert_eq!(scene.positions, loaded);
}
