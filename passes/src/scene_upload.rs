//! The scene on the GPU: the six arrays of `parallax_scene::gpu::GpuScene` as global buffers of
//! the executor (reached by buffer address), its textures as the backend's sampled-texture
//! array. Uploaded once per scene; every pass that reads the scene finds it by name. A scene
//! whose meshes move ([`parallax_scene::Scene::pose_at`]) re-uploads only its geometry
//! ([`upload_geometry`]) for each new pose.

use parallax_backend::{Executor, Recorder, TextureData};
use parallax_scene::gpu::GpuScene;

use crate::error::Result;
use crate::shaders::SceneRefs;

/// Global buffer names, in the order of `SceneRefs` in shaders/pt_types.glsl.
pub const SCENE_BUFFERS: [&str; 6] =
    ["scene.nodes", "scene.triangles", "scene.attributes", "scene.materials", "scene.emissive", "scene.lights"];

/// Uploads `scene` on every device of `executor`: BVH nodes, BVH-ordered triangles and their
/// attributes, materials, emissive-triangle table, punctual lights, textures. Replaces a
/// previously uploaded scene.
pub fn upload_scene(executor: &mut Executor, scene: &GpuScene<'_>) -> Result<()> {
    upload_geometry(executor, scene)?;
    executor.upload_buffer("scene.materials", scene.material_bytes())?;
    executor.upload_buffer("scene.lights", scene.light_bytes())?;
    let textures: Vec<TextureData<'_>> =
        scene.textures.iter().map(|t| TextureData { width: t.width, height: t.height, rgba8: &t.rgba8 }).collect();
    executor.upload_textures(&textures)?;
    Ok(())
}

/// Uploads what a new pose of the same scene changes: BVH nodes, BVH-ordered triangles and
/// their attributes (normals, emissive areas), and the emissive-triangle table (its
/// probabilities follow the areas); materials, lights and textures stay. The executor waits for
/// the frames in flight before it overwrites a buffer ([`Executor::upload_buffer`]); a buffer of
/// the same size (triangles always, BVH nodes when the build gives as many) keeps its address
/// and the recorded command buffers.
pub fn upload_geometry(executor: &mut Executor, scene: &GpuScene<'_>) -> Result<()> {
    for (name, bytes) in geometry_arrays(scene) {
        executor.upload_buffer(name, bytes)?;
    }
    Ok(())
}

/// The global buffers a pose of `scene` fills, by name.
fn geometry_arrays<'a>(scene: &'a GpuScene<'_>) -> [(&'static str, &'a [u8]); 4] {
    [
        ("scene.nodes", scene.node_bytes()),
        ("scene.triangles", scene.triangle_bytes()),
        ("scene.attributes", scene.attribute_bytes()),
        ("scene.emissive", scene.emissive_bytes()),
    ]
}

/// Device-local bytes [`upload_scene`] allocates on each device: the six arrays and the
/// textures (RGBA8, one level each), known before the upload.
pub fn scene_device_bytes(scene: &GpuScene<'_>) -> u64 {
    let arrays =
        geometry_arrays(scene).map(|(_, bytes)| bytes).into_iter().chain([scene.material_bytes(), scene.light_bytes()]);
    let textures = scene.textures.iter().map(|t| t.rgba8.len() as u64);
    arrays.map(|bytes| bytes.len() as u64).chain(textures).sum()
}

/// The scene's buffer addresses on the device being recorded, as kernels push them.
pub(crate) fn scene_refs(rec: &Recorder<'_>) -> parallax_backend::Result<SceneRefs> {
    let [nodes, triangles, attributes, materials, emissive, lights] =
        SCENE_BUFFERS.map(|name| rec.buffer_address(name));
    Ok(SceneRefs {
        nodes: nodes?,
        triangles: triangles?,
        attributes: attributes?,
        materials: materials?,
        emissive: emissive?,
        lights: lights?,
    })
}
