//! glTF 2.0 import into the flat [`Scene`] model.
//!
//! Supports what the scenes in `shared/scenes` use and nothing more: triangle meshes (indexed or
//! not; flat normals generated when a primitive has none), node transforms, skinning and node
//! animation (meshes posed at t = 0 of the file's first animation, or in the rest pose without
//! one, so that skinned models such as Fox stand where a viewer shows them; [`crate::posing`]
//! poses them at any other time), metallic-roughness materials
//! with KHR_materials_emissive_strength, alpha MASK, double-sided, KHR_lights_punctual and
//! perspective cameras. Images are decoded once, in parallel, to RGBA8.
//!
//! Every failure is a [`SceneError`] naming the file. The gltf crate's accessor readers slice
//! buffers without checking, so every accessor is bounds-checked here before any is read.

use std::path::Path;

use glam::{Mat3, Mat4, Vec3, Vec4};
use rayon::prelude::*;

use crate::animation::AnimatedNode;
use crate::camera::Camera;
use crate::error::SceneError;
use crate::gltf_budget::{
    ImageSource, LoadEstimate, MemoryLimit, distinct_sources, image_dimensions, triangles_after_instancing,
};
use crate::gltf_primitive::{PrimitiveAt, Vertices, corners, lay_out, pose, read_skin_weights, read_vertices};
use crate::input::{
    IMAGE_FILE_LIMIT, IMAGE_SIDE_LIMIT, SCENE_FILE_LIMIT, SourceFile, UriPolicy, read_bounded, read_prefix, resolve_uri,
};
use crate::limits::{MAX_COORDINATE, MAX_EMISSION};
use crate::model::{AlphaMode, Material, PunctualKind, PunctualLight, Scene, Texture};
use crate::posing::{GeometryAnimation, MovingPrimitive, Skin, Skinning};

/// Extensions a file may list in `extensionsRequired`.
pub const SUPPORTED_REQUIRED_EXTENSIONS: &[&str] = &["KHR_materials_emissive_strength", "KHR_lights_punctual"];
const SUPPORTED_LIST: &str = "KHR_materials_emissive_strength, KHR_lights_punctual";

/// How a glTF file is read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Where buffer and image URIs may point (default: inside the scene's folder tree).
    pub uris: UriPolicy,
    /// The memory the load may take (the process's budget); None: only the stated limits of
    /// [`crate::gltf_budget`] apply.
    pub memory: Option<MemoryLimit>,
}

/// Loads a `.gltf` (with external or embedded buffers) or `.glb` file.
pub fn load_gltf(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
    load_gltf_with(path, LoadOptions::default())
}

/// [`load_gltf`] with `options`. [`Scene::sources`] lists every file read: the scene file, then
/// the buffers and images it names.
pub fn load_gltf_with(path: impl AsRef<Path>, options: LoadOptions) -> Result<Scene, SceneError> {
    let path = path.as_ref();
    let bytes = read_bounded(path, SCENE_FILE_LIMIT, "glTF scene")?;
    let base = path.parent().unwrap_or(Path::new("."));
    let mut scene = load_gltf_bytes_with(&bytes, base, path, options)?;
    let name = path.file_name().map_or(path.to_string_lossy(), |n| n.to_string_lossy());
    scene.sources.insert(0, SourceFile::of(name, path, &bytes));
    Ok(scene)
}

/// Loads glTF from memory; relative URIs resolve against `base_dir`; errors name `path`.
pub fn load_gltf_bytes(bytes: &[u8], base_dir: &Path, path: &Path) -> Result<Scene, SceneError> {
    load_gltf_bytes_with(bytes, base_dir, path, LoadOptions::default())
}

/// [`load_gltf_bytes`] with `options`.
pub fn load_gltf_bytes_with(
    bytes: &[u8],
    base_dir: &Path,
    path: &Path,
    options: LoadOptions,
) -> Result<Scene, SceneError> {
    let path_buf = path.to_path_buf();
    // A malformed file must never take the process down: the checks below are meant to catch
    // everything, and this is the backstop if the gltf crate panics on an input we missed. The
    // panic's own text (a source line of the crate) would tell the user nothing: it is kept
    // off stderr while the file is read, and the error says what to do.
    let previous_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let result = std::panic::catch_unwind(|| import(bytes, base_dir, path, options));
    std::panic::set_hook(previous_hook);
    result.unwrap_or_else(|_| {
        Err(SceneError::InvalidGltf {
            path: path_buf,
            detail: "the glTF reader failed on a construct Parallax does not check yet; check the file with the \
                     Khronos glTF validator"
                .into(),
        })
    })
}

struct Importer<'a> {
    path: &'a Path,
    doc: &'a gltf::Document,
    buffers: &'a [gltf::buffer::Data],
    scene: Scene,
    /// glTF material index -> scene material index (the default material is appended lazily).
    default_material: Option<u32>,
    /// The first mesh node whose world transform flattens everything (determinant 0): the
    /// likely cause when the whole scene has zero area.
    zero_scale_node: Option<usize>,
    /// Node and yfov of the first perspective camera (the scene's default camera).
    first_camera: Option<(usize, f32)>,
    /// glTF image index -> texture index: image entries that name one source share a texture.
    image_texture: Vec<u32>,
    /// Every node with the tracks of the file's first animation, and its duration.
    animation: Option<(Vec<AnimatedNode>, f32)>,
    /// The primitives the animation moves, as the file has them.
    moving: Vec<MovingPrimitive>,
}

fn import(bytes: &[u8], base_dir: &Path, path: &Path, options: LoadOptions) -> Result<Scene, SceneError> {
    let p = || path.to_path_buf();
    check_container(bytes, path)?;
    // Parse without validation first, so that an unsupported required extension is reported
    // by name rather than as a generic validation failure.
    let raw = gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| SceneError::MalformedJson { path: p(), detail: e.to_string() })?;
    if let Some(ext) = raw.document.extensions_required().find(|e| !SUPPORTED_REQUIRED_EXTENSIONS.contains(e)) {
        return Err(SceneError::UnsupportedExtension {
            path: p(),
            extension: ext.to_string(),
            supported: SUPPORTED_LIST,
        });
    }
    // gltf-json's own validation indexes the POSITION accessor before checking that it
    // exists (a panic on bad files), so that one reference is checked here first.
    let root = raw.document.as_json();
    for (mi, mesh) in root.meshes.iter().enumerate() {
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            if let Some(bad) = prim.attributes.values().find(|a| a.value() >= root.accessors.len()) {
                return Err(SceneError::InvalidGltf {
                    path: p(),
                    detail: format!(
                        "mesh {mi} primitive {pi} names accessor {} of {}",
                        bad.value(),
                        root.accessors.len()
                    ),
                });
            }
        }
    }
    check_images(root, path)?;
    drop(raw);
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| match e {
        gltf::Error::Validation(errors) => SceneError::InvalidGltf {
            path: p(),
            detail: errors.iter().take(3).map(|(at, err)| format!("{at}: {err}")).collect::<Vec<_>>().join("; "),
        },
        other => SceneError::MalformedJson { path: p(), detail: other.to_string() },
    })?;
    let gltf::Gltf { document, blob } = gltf;
    let mut sources = Vec::new();
    // Counted from the JSON alone: a refusal reads no buffer.
    let triangles = triangles_after_instancing(&document);
    LoadEstimate::check_triangles(triangles, path)?;
    let buffers = load_buffers(&document, base_dir, blob, path, options.uris, &mut sources)?;
    check_accessors(&document, &buffers, path)?;
    let images = load_images(&document, &buffers, base_dir, path, options, triangles)?;
    sources.extend(images.sources);

    let mut imp = Importer {
        path,
        doc: &document,
        buffers: &buffers,
        scene: Scene {
            name: path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
            textures: images.textures,
            sources,
            ..Default::default()
        },
        image_texture: images.of_entry,
        default_material: None,
        zero_scale_node: None,
        first_camera: None,
        animation: crate::gltf_animation::first_animation_nodes(&document, &buffers, path)?,
        moving: Vec::new(),
    };
    imp.import_materials()?;
    imp.import_nodes()?;
    if imp.scene.triangles.is_empty() {
        return Err(SceneError::NoGeometry { path: p() });
    }
    if imp.scene.surface_area() == 0.0 {
        let hint = match imp.zero_scale_node {
            Some(node) => format!("node {node} has a transform of zero scale"),
            None => "the vertices of each triangle coincide or are collinear".into(),
        };
        return Err(SceneError::ZeroArea { path: p(), hint });
    }
    imp.scene.check().map_err(|detail| SceneError::InvalidGltf { path: p(), detail })?;
    if let Some((node, yfov)) = imp.first_camera {
        imp.scene.camera_animation = crate::gltf_animation::camera_animation(&document, &buffers, node, yfov, path)?;
    }
    Ok(imp.scene)
}

impl Importer<'_> {
    fn err_unsupported(&self, what: impl Into<String>) -> SceneError {
        SceneError::Unsupported { path: self.path.to_path_buf(), what: what.into() }
    }

    fn import_materials(&mut self) -> Result<(), SceneError> {
        let mut materials = Vec::new();
        for m in self.doc.materials() {
            let pbr = m.pbr_metallic_roughness();
            let tex = |info: Option<gltf::texture::Info>| -> Result<Option<u32>, SceneError> {
                match info {
                    None => Ok(None),
                    Some(i) if i.tex_coord() != 0 => Err(self.err_unsupported(format!(
                        "TEXCOORD_{} in material {}",
                        i.tex_coord(),
                        m.index().unwrap_or(0)
                    ))),
                    Some(i) => Ok(Some(self.image_texture[i.texture().source().index()])),
                }
            };
            let alpha_mode = match m.alpha_mode() {
                gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
                gltf::material::AlphaMode::Mask => AlphaMode::Mask(m.alpha_cutoff().unwrap_or(0.5)),
                gltf::material::AlphaMode::Blend => AlphaMode::Mask(0.5),
            };
            let emissive = Vec3::from(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0);
            let material = Material {
                name: m.name().unwrap_or("").to_string(),
                base_color: Vec4::from(pbr.base_color_factor()),
                base_color_texture: tex(pbr.base_color_texture())?,
                metallic: pbr.metallic_factor(),
                roughness: pbr.roughness_factor(),
                metallic_roughness_texture: tex(pbr.metallic_roughness_texture())?,
                emissive,
                emissive_texture: tex(m.emissive_texture())?,
                alpha_mode,
                double_sided: m.double_sided(),
                specular: 1.0,
            };
            let finite = material.base_color.is_finite()
                && material.emissive.is_finite()
                && material.metallic.is_finite()
                && material.roughness.is_finite();
            if !finite {
                return Err(SceneError::NonFinite {
                    path: self.path.to_path_buf(),
                    what: format!("material {}", materials.len()),
                });
            }
            check_emission(self.path, || format!("material {} (emissive)", materials.len()), material.emissive)?;
            materials.push(material);
        }
        self.scene.materials = materials;
        Ok(())
    }

    fn material_index(&mut self, prim: &gltf::Primitive) -> u32 {
        match prim.material().index() {
            Some(i) => i as u32,
            None => *self.default_material.get_or_insert_with(|| {
                self.scene.materials.push(Material::default());
                (self.scene.materials.len() - 1) as u32
            }),
        }
    }

    fn import_nodes(&mut self) -> Result<(), SceneError> {
        // World matrices of every node first: skins need their joints' matrices.
        let node_count = self.doc.nodes().len();
        let mut world = vec![Mat4::IDENTITY; node_count];
        let mut in_scene = vec![false; node_count];
        let roots: Vec<usize> = match self.doc.default_scene().or_else(|| self.doc.scenes().next()) {
            Some(s) => s.nodes().map(|n| n.index()).collect(),
            None => {
                // No scene: every node that is nobody's child is a root.
                let mut is_child = vec![false; node_count];
                for n in self.doc.nodes() {
                    for c in n.children() {
                        is_child[c.index()] = true;
                    }
                }
                (0..node_count).filter(|&i| !is_child[i]).collect()
            }
        };
        let nodes: Vec<gltf::Node> = self.doc.nodes().collect();
        let mut stack: Vec<(usize, Option<usize>, usize)> = roots.iter().map(|&r| (r, None, 0)).collect();
        // Each node after its parent.
        let mut parented = Vec::new();
        while let Some((i, parent, depth)) = stack.pop() {
            if in_scene[i] || depth > node_count {
                // A node reachable twice means a cycle or shared child: the glTF spec forbids both.
                return Err(SceneError::InvalidGltf {
                    path: self.path.to_path_buf(),
                    detail: format!("node {i} is reachable more than once (cycle or shared child)"),
                });
            }
            in_scene[i] = true;
            let local = Mat4::from_cols_array_2d(&nodes[i].transform().matrix());
            world[i] = parent.map_or(Mat4::IDENTITY, |p| world[p]) * local;
            if !world[i].is_finite() {
                return Err(SceneError::NonFinite {
                    path: self.path.to_path_buf(),
                    what: format!("transform of node {i}"),
                });
            }
            parented.push((i, parent));
            for c in nodes[i].children() {
                stack.push((c.index(), Some(i), depth + 1));
            }
        }
        // Meshes stand as at t = 0 of the animation; cameras and lights in the rest pose (the
        // camera's own animation is read apart, [`crate::gltf_animation::camera_animation`]).
        let animation = self.animation.take().map(|(nodes, duration)| GeometryAnimation {
            path: self.path.to_path_buf(),
            nodes,
            order: parented.clone(),
            duration,
            primitives: Vec::new(),
        });
        let start = animation.as_ref().map(|a| a.world_matrices(0.0));
        let mesh_world = start.as_deref().unwrap_or(&world);
        let mut moves = vec![false; node_count];
        if let Some(a) = &animation {
            for &(i, parent) in &parented {
                moves[i] = a.nodes[i].is_animated() || parent.is_some_and(|p| moves[p]);
            }
        }
        let mut order: Vec<usize> = parented.iter().map(|&(i, _)| i).collect();
        order.sort_unstable(); // deterministic triangle order, independent of traversal
        for i in order {
            let node = &nodes[i];
            if let Some(mesh) = node.mesh() {
                if Mat3::from_mat4(mesh_world[i]).determinant() == 0.0 && node.skin().is_none() {
                    self.zero_scale_node.get_or_insert(i);
                }
                let skin = node.skin().map(|s| self.read_skin(&s)).transpose()?;
                let joint_matrices = skin.as_ref().map(|s| s.joint_matrices(mesh_world));
                let skin_moves = skin.as_ref().is_some_and(|s| s.joints.iter().any(|&j| moves[j]));
                for prim in mesh.primitives() {
                    let skinned = skin.as_ref().zip(joint_matrices.as_deref());
                    self.import_primitive(i, &mesh, &prim, mesh_world[i], skinned, (moves[i], skin_moves))?;
                }
            }
            if let Some(cam) = node.camera() {
                // Orthographic cameras are skipped: nothing we render uses them.
                if let gltf::camera::Projection::Perspective(p) = cam.projection() {
                    let camera = Camera::from_world_matrix(world[i], p.yfov());
                    self.check_camera(cam.index(), i, p.yfov(), world[i])?;
                    self.first_camera.get_or_insert((i, p.yfov()));
                    self.scene.cameras.push(camera);
                }
            }
            if let Some(light) = node.light() {
                let punctual = light_from_gltf(&light, world[i]);
                let what = || format!("light {} (node {i})", light.index());
                if !punctual.intensity.is_finite() || !punctual.color.is_finite() {
                    return Err(SceneError::NonFinite { path: self.path.to_path_buf(), what: what() });
                }
                check_emission(self.path, what, punctual.color * punctual.intensity)?;
                self.scene.lights.push(punctual);
            }
        }
        // A scene whose animation moves no mesh, or holds one pose (a single keyframe), is
        // still: it needs no posing per frame.
        self.scene.geometry_animation = animation
            .filter(|a| a.duration > 0.0 && !self.moving.is_empty())
            .map(|a| GeometryAnimation { primitives: std::mem::take(&mut self.moving), ..a });
        Ok(())
    }

    /// A camera the renderer can use: the spec's 0 < yfov < π, and a node transform that keeps
    /// a view direction and an up direction apart (a zero scale would silently point it down -Z).
    fn check_camera(&self, camera: usize, node: usize, yfov: f32, world: Mat4) -> Result<(), SceneError> {
        let bad = |detail: String| SceneError::BadCamera { path: self.path.to_path_buf(), camera, node, detail };
        if !(yfov.is_finite() && yfov > 0.0 && yfov < std::f32::consts::PI) {
            return Err(bad(format!("yfov {yfov} rad is outside 0 < yfov < π (glTF spec); use e.g. 0.8")));
        }
        let forward = world.transform_vector3(Vec3::NEG_Z);
        let up = world.transform_vector3(Vec3::Y);
        if forward.cross(up).length_squared() <= f32::MIN_POSITIVE {
            return Err(bad("its node transform has zero scale, so the camera has no view direction".into()));
        }
        Ok(())
    }

    /// The skin's joints and inverse bind matrices.
    fn read_skin(&self, skin: &gltf::Skin) -> Result<Skin, SceneError> {
        if let Some(a) = skin.inverse_bind_matrices() {
            if a.data_type() != gltf::accessor::DataType::F32 || a.dimensions() != gltf::accessor::Dimensions::Mat4 {
                return Err(SceneError::InvalidGltf {
                    path: self.path.to_path_buf(),
                    detail: format!("skin {} inverse bind matrices are not float MAT4", skin.index()),
                });
            }
        }
        let reader = skin.reader(|b| Some(&self.buffers[b.index()].0[..]));
        let ibms: Vec<Mat4> = match reader.read_inverse_bind_matrices() {
            Some(it) => it.map(|m| Mat4::from_cols_array_2d(&m)).collect(),
            None => vec![Mat4::IDENTITY; skin.joints().len()],
        };
        if ibms.len() < skin.joints().len() {
            return Err(SceneError::InvalidGltf {
                path: self.path.to_path_buf(),
                detail: format!("skin {} has fewer inverse bind matrices than joints", skin.index()),
            });
        }
        Ok(Skin { joints: skin.joints().map(|j| j.index()).collect(), inverse_bind: ibms })
    }

    /// Imports one primitive of `node`, placed by the node's `world` or, when the node has a skin,
    /// by the skin and its joint matrices; `(node_moves, skin_moves)`: whether the animation
    /// moves the node and the skin's joints, which keeps the primitive for posing.
    fn import_primitive(
        &mut self,
        node: usize,
        mesh: &gltf::Mesh,
        prim: &gltf::Primitive,
        world: Mat4,
        skin: Option<(&Skin, &[Mat4])>,
        (node_moves, skin_moves): (bool, bool),
    ) -> Result<(), SceneError> {
        let at = PrimitiveAt { path: self.path, mesh: mesh.index(), primitive: prim.index() };
        if prim.mode() != gltf::mesh::Mode::Triangles {
            return Err(at.bad(format!("mode {:?} (only TRIANGLES is supported)", prim.mode())));
        }
        check_attribute_types(prim).map_err(|what| at.bad(what))?;
        let mut vertices = read_vertices(prim, self.buffers, &at)?;
        let vertex_count = vertices.positions.len();
        let weights = read_skin_weights(prim, self.buffers, skin.map(|(s, _)| s.joints.len()), vertex_count, &at)?;
        let skinning = weights.as_ref().zip(skin).map(|(w, (_, joint_matrices))| w.matrices(joint_matrices));
        // The glTF spec ignores a skinned mesh's node transform: only its joints move it.
        let moves = if skinning.is_some() { skin_moves } else { node_moves };
        let as_in_file =
            moves.then(|| (vertices.positions.clone(), vertices.normals.clone(), vertices.indices.clone()));
        pose(&mut vertices.positions, vertices.normals.as_deref_mut(), skinning.as_deref(), world);
        let positions = &vertices.positions;
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(SceneError::NonFinite {
                path: self.path.to_path_buf(),
                what: format!("positions of mesh {} primitive {}", mesh.index(), prim.index()),
            });
        }
        // The obvhs CWBVH builder panics on coordinates near f32's range (docs/UPSTREAM.md), and
        // traversal would overflow long before that: refuse them here, before any BVH exists.
        if let Some((k, p)) = positions.iter().enumerate().find(|(_, p)| p.abs().max_element() > MAX_COORDINATE) {
            let accessor = prim.get(&gltf::Semantic::Positions).map_or(0, |a| a.index());
            return Err(SceneError::CoordinateOutOfRange {
                path: self.path.to_path_buf(),
                what: format!(
                    "vertex {k} of accessor {accessor} (node {node}, mesh {} primitive {}) in world space",
                    mesh.index(),
                    prim.index()
                ),
                value: p.abs().max_element(),
                limit: MAX_COORDINATE,
            });
        }
        // A mirroring transform reverses the winding (glTF spec); flip it back so that
        // counter-clockwise stays front-facing.
        let mirrored = skinning.is_none() && Mat3::from_mat4(world).determinant() < 0.0;
        let material = self.material_index(prim);
        if let Some((positions, normals, indices)) = as_in_file {
            self.moving.push(MovingPrimitive {
                mesh: mesh.index(),
                primitive: prim.index(),
                node,
                first_vertex: self.scene.positions.len(),
                positions,
                normals,
                indices,
                mirrored,
                skin: skin.zip(weights).map(|((skin, _), weights)| Skinning { skin: skin.clone(), weights }),
            });
        }
        append_triangles(&mut self.scene, vertices, mirrored, material);
        Ok(())
    }
}

/// Appends the triangles with `material`, laid out by [`lay_out`]: reversing the winding of a
/// `mirrored` primitive so that counter-clockwise stays front-facing; without normals each
/// triangle gets its own three vertices with the face normal.
fn append_triangles(s: &mut Scene, vertices: Vertices, mirrored: bool, material: u32) {
    let Vertices { positions, normals, uvs, indices } = vertices;
    let base = s.positions.len() as u32;
    let flat = normals.is_none();
    let (positions, normals) = lay_out(&indices, positions, normals, mirrored);
    s.positions.extend(positions);
    s.normals.extend(normals);
    for (t, c) in corners(&indices, mirrored).enumerate() {
        let triangle = if flat {
            // Flat normals need one vertex per triangle corner.
            s.uvs.extend(c.map(|i| uvs[i]));
            let first = base + 3 * t as u32;
            [first, first + 1, first + 2]
        } else {
            c.map(|i| base + i as u32)
        };
        s.triangles.push(triangle);
        s.triangle_materials.push(material);
    }
    if !flat {
        s.uvs.extend(uvs);
    }
}

/// Emission must be non-negative and at most [`MAX_EMISSION`] per channel.
fn check_emission(path: &Path, what: impl Fn() -> String, emission: Vec3) -> Result<(), SceneError> {
    if emission.min_element() < 0.0 {
        return Err(SceneError::InvalidGltf {
            path: path.to_path_buf(),
            detail: format!("{} has a negative emission {emission}; glTF requires non-negative values", what()),
        });
    }
    if emission.max_element() > MAX_EMISSION {
        return Err(SceneError::EmissionOutOfRange {
            path: path.to_path_buf(),
            what: what(),
            value: emission.max_element(),
            limit: MAX_EMISSION,
        });
    }
    Ok(())
}

/// Tells a glTF file from anything else before the JSON parser does, whose "malformed JSON" would
/// send the owner of an .obj or a truncated .glb looking for a syntax error.
fn check_container(bytes: &[u8], path: &Path) -> Result<(), SceneError> {
    let not_gltf = |detail: &str| Err(SceneError::NotGltf { path: path.to_path_buf(), detail: detail.into() });
    let is_glb_name = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    if bytes.starts_with(b"glTF") {
        return Ok(());
    }
    if is_glb_name {
        return not_gltf("a .glb file must start with the binary glTF magic `glTF`");
    }
    match bytes.iter().find(|b| !b.is_ascii_whitespace()) {
        Some(b'{') => Ok(()),
        Some(_) => not_gltf("the file is neither JSON nor binary glTF"),
        None => not_gltf("the file is empty"),
    }
}

/// The gltf crate's readers assume spec-conforming component types and hit `unreachable!` or
/// misread otherwise; its validation does not check them, so this does.
fn check_attribute_types(prim: &gltf::Primitive) -> Result<(), String> {
    use gltf::accessor::{DataType as T, Dimensions as D};
    use gltf::mesh::Semantic;
    let ok = |a: &gltf::Accessor, types: &[T], dims: D| types.contains(&a.data_type()) && a.dimensions() == dims;
    for (semantic, a) in prim.attributes() {
        let fine = match semantic {
            Semantic::Positions | Semantic::Normals => ok(&a, &[T::F32], D::Vec3),
            Semantic::TexCoords(_) => ok(&a, &[T::F32, T::U8, T::U16], D::Vec2),
            Semantic::Joints(_) => ok(&a, &[T::U8, T::U16], D::Vec4),
            Semantic::Weights(_) => ok(&a, &[T::F32, T::U8, T::U16], D::Vec4),
            // Not read by the importer.
            _ => true,
        };
        if !fine {
            return Err(format!(
                "attribute {semantic:?} has type {:?} {:?}, which glTF does not allow",
                a.data_type(),
                a.dimensions()
            ));
        }
    }
    if let Some(i) = prim.indices() {
        if !ok(&i, &[T::U8, T::U16, T::U32], D::Scalar) {
            return Err(format!("indices have type {:?} {:?}", i.data_type(), i.dimensions()));
        }
    }
    Ok(())
}

fn light_from_gltf(light: &gltf::khr_lights_punctual::Light, world: Mat4) -> PunctualLight {
    use gltf::khr_lights_punctual::Kind;
    let kind = match light.kind() {
        Kind::Point => PunctualKind::Point,
        Kind::Directional => PunctualKind::Directional,
        Kind::Spot { inner_cone_angle, outer_cone_angle } => {
            PunctualKind::Spot { inner_cone: inner_cone_angle, outer_cone: outer_cone_angle }
        }
    };
    PunctualLight {
        kind,
        position: world.transform_point3(Vec3::ZERO),
        direction: world.transform_vector3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z),
        color: Vec3::from(light.color()),
        intensity: light.intensity(),
    }
}

fn buffer_uri(buffer: &gltf::Buffer) -> String {
    match buffer.source() {
        gltf::buffer::Source::Bin => "GLB binary chunk".into(),
        gltf::buffer::Source::Uri(u) if u.starts_with("data:") => "embedded data URI".into(),
        gltf::buffer::Source::Uri(u) => u.to_string(),
    }
}

/// Each buffer's bytes: the GLB chunk, a data: URI, or a file inside the scene's folder read up
/// to its declared `byteLength` (never more, whatever the file is). The gltf crate's own
/// `import_buffers` reads a whole file of any kind and panics on bad percent-encoding.
fn load_buffers(
    doc: &gltf::Document,
    base_dir: &Path,
    mut blob: Option<Vec<u8>>,
    path: &Path,
    policy: UriPolicy,
    sources: &mut Vec<SourceFile>,
) -> Result<Vec<gltf::buffer::Data>, SceneError> {
    let mut buffers = Vec::new();
    for buffer in doc.buffers() {
        let missing = |detail: String| SceneError::MissingBuffer {
            path: path.to_path_buf(),
            buffer: buffer.index(),
            uri: buffer_uri(&buffer),
            detail,
        };
        let declared = buffer.length() as u64;
        if declared > SCENE_FILE_LIMIT {
            return Err(missing(format!(
                "its byteLength {declared} is more than the {SCENE_FILE_LIMIT} bytes a buffer may have"
            )));
        }
        let mut data = match buffer.source() {
            gltf::buffer::Source::Bin => {
                blob.take().ok_or_else(|| missing("the file has no GLB binary chunk".into()))?
            }
            source @ gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                gltf::buffer::Data::from_source(source, None).map_err(|e| missing(e.to_string()))?.0
            }
            gltf::buffer::Source::Uri(uri) => {
                let file = resolve_uri(base_dir, uri, policy).map_err(missing)?;
                let bytes = read_prefix(&file, declared).map_err(|e| missing(e.to_string()))?;
                sources.push(SourceFile::of(uri, &file, &bytes));
                bytes
            }
        };
        if (data.len() as u64) < declared {
            return Err(missing(format!("expected {declared} bytes, found {}", data.len())));
        }
        // As the gltf crate pads them: its readers may read whole 4-byte words.
        data.resize(data.len().next_multiple_of(4), 0);
        buffers.push(gltf::buffer::Data(data));
    }
    Ok(buffers)
}

/// What the gltf crate's `Image::source` unwraps: exactly one of `uri` and `bufferView` (glTF
/// 2.0, 5.18), a `mimeType` with a `bufferView`, and a view that exists.
fn check_images(root: &gltf::json::Root, path: &Path) -> Result<(), SceneError> {
    for (image, json) in root.images.iter().enumerate() {
        let bad = |detail: &str| SceneError::MalformedImage { path: path.to_path_buf(), image, detail: detail.into() };
        match (&json.uri, &json.buffer_view) {
            (None, None) => return Err(bad("has neither uri nor bufferView; glTF requires exactly one")),
            (Some(_), Some(_)) => return Err(bad("has both uri and bufferView; glTF requires exactly one")),
            (None, Some(view)) if view.value() >= root.buffer_views.len() => {
                return Err(bad(&format!("names bufferView {} of {}", view.value(), root.buffer_views.len())));
            }
            (None, Some(_)) if json.mime_type.is_none() => {
                return Err(bad("has a bufferView but no mimeType; glTF requires one (image/png or image/jpeg)"));
            }
            _ => {}
        }
    }
    Ok(())
}

/// Every accessor must lie inside its buffer view and every view inside its buffer: the gltf
/// crate's readers index without checking.
fn check_accessors(doc: &gltf::Document, buffers: &[gltf::buffer::Data], path: &Path) -> Result<(), SceneError> {
    for view in doc.views() {
        let len = buffers.get(view.buffer().index()).map_or(0, |b| b.len());
        let end = view.offset().checked_add(view.length());
        if end.is_none_or(|e| e > len) {
            return Err(SceneError::InvalidGltf {
                path: path.to_path_buf(),
                detail: format!("buffer view {} reads past the end of its buffer", view.index()),
            });
        }
    }
    for acc in doc.accessors() {
        let oob = || SceneError::AccessorOutOfBounds { path: path.to_path_buf(), accessor: acc.index() };
        if acc.sparse().is_some() {
            return Err(SceneError::Unsupported {
                path: path.to_path_buf(),
                what: format!("sparse accessor {}", acc.index()),
            });
        }
        let Some(view) = acc.view() else {
            return Err(oob());
        };
        // The spec requires count >= 1, and the gltf reader underflows on 0.
        if acc.count() == 0 {
            return Err(oob());
        }
        let size = acc.size();
        let stride = view.stride().unwrap_or(size);
        if stride < size {
            return Err(oob());
        }
        let end = (acc.count() - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(size))
            .and_then(|x| x.checked_add(acc.offset()));
        if end.is_none_or(|e| e > view.length()) {
            return Err(oob());
        }
    }
    Ok(())
}

/// The distinct images of a file decoded once each, the texture of every image entry, and the
/// files read.
struct Images {
    textures: Vec<Texture>,
    of_entry: Vec<u32>,
    sources: Vec<SourceFile>,
}

/// Shares image entries by source, reads each distinct image's size from its header, checks
/// the estimate of the whole load (`triangles` after instancing, textures after sharing), and
/// only then decodes each distinct image once, in parallel.
fn load_images(
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    base_dir: &Path,
    path: &Path,
    options: LoadOptions,
    triangles: u64,
) -> Result<Images, SceneError> {
    let entries: Vec<gltf::Image> = doc.images().collect();
    let (distinct, of_entry) = distinct_sources(
        entries
            .iter()
            .map(|img| match img.source() {
                gltf::image::Source::View { view, .. } => ImageSource::View(view.index()),
                gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => {
                    resolve_uri(base_dir, uri, options.uris)
                        .map_or(ImageSource::Unreadable(img.index()), ImageSource::File)
                }
                gltf::image::Source::Uri { .. } => ImageSource::Unreadable(img.index()),
            })
            .collect(),
    );
    // Each distinct image is named, in errors, by its first entry.
    let first: Vec<&gltf::Image> =
        (0..distinct.len()).map(|d| &entries[of_entry.iter().position(|&e| e as usize == d).expect("used")]).collect();
    let bad = |img: &gltf::Image, detail: String| SceneError::BadImage {
        path: path.to_path_buf(),
        image: img.index(),
        uri: image_uri(img),
        detail,
    };
    let view_bytes = |view: &gltf::buffer::View| -> Result<&[u8], String> {
        buffers[view.buffer().index()]
            .0
            .get(view.offset()..view.offset() + view.length())
            .ok_or_else(|| "buffer view out of range".to_string())
    };
    let mut estimate = LoadEstimate {
        triangles,
        images: entries.len(),
        distinct_images: distinct.len(),
        texture_bytes: 0,
        largest_decode_bytes: 0,
    };
    for (source, img) in distinct.iter().zip(&first) {
        let size = match (source, img.source()) {
            (ImageSource::File(file), _) => crate::input::open_regular(file)
                .map_err(|e| e.to_string())
                .and_then(|(f, _)| image_dimensions(std::io::BufReader::new(f))),
            (ImageSource::View(_), gltf::image::Source::View { view, .. }) => {
                view_bytes(&view).and_then(|b| image_dimensions(std::io::Cursor::new(b)))
            }
            // Decoding says why it cannot be read.
            _ => Ok((0, 0)),
        }
        .map_err(|detail| bad(img, detail))?;
        if size.0 > IMAGE_SIDE_LIMIT || size.1 > IMAGE_SIDE_LIMIT {
            return Err(bad(img, too_large_image()));
        }
        let pixels = u64::from(size.0) * u64::from(size.1);
        estimate.texture_bytes += 4 * pixels;
        estimate.largest_decode_bytes = estimate.largest_decode_bytes.max(8 * pixels);
    }
    estimate.check(path, options.memory)?;
    let decoded: Vec<(Texture, Option<SourceFile>)> = distinct
        .par_iter()
        .zip(first.par_iter())
        .map(|(source, img)| {
            let mut file = None;
            let encoded: Result<std::borrow::Cow<[u8]>, String> = match (source, img.source()) {
                (ImageSource::View(_), gltf::image::Source::View { view, .. }) => view_bytes(&view).map(Into::into),
                (ImageSource::File(resolved), _) => {
                    file = Some(resolved);
                    read_bounded(resolved, IMAGE_FILE_LIMIT, "glTF image").map(Into::into).map_err(|e| e.to_string())
                }
                (_, gltf::image::Source::Uri { uri, .. }) if uri.starts_with("data:") => {
                    Err("embedded data: URI images are not supported".into())
                }
                // Only a URI that cannot be resolved is left: say why.
                (_, gltf::image::Source::Uri { uri, .. }) => Err(resolve_uri(base_dir, uri, options.uris)
                    .err()
                    .unwrap_or_else(|| format!("{uri} cannot be resolved"))),
                (_, gltf::image::Source::View { .. }) => unreachable!("a buffer view is always a View source"),
            };
            let encoded = encoded.map_err(|detail| bad(img, detail))?;
            let rgba = decode_bounded(&encoded).map_err(|detail| bad(img, detail))?;
            let source = file.map(|file| SourceFile::of(image_uri(img), file, &encoded));
            Ok((Texture { width: rgba.width(), height: rgba.height(), rgba8: rgba.into_raw() }, source))
        })
        .collect::<Result<_, SceneError>>()?;
    let (textures, sources): (Vec<Texture>, Vec<Option<SourceFile>>) = decoded.into_iter().unzip();
    Ok(Images { textures, of_entry, sources: sources.into_iter().flatten().collect() })
}

/// How an image entry is named in errors: its URI, or where its bytes are.
fn image_uri(img: &gltf::Image) -> String {
    match img.source() {
        gltf::image::Source::View { view, .. } => format!("buffer view {}", view.index()),
        gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => "data URI".into(),
        gltf::image::Source::Uri { uri, .. } => uri.to_string(),
    }
}

fn too_large_image() -> String {
    format!("larger than {IMAGE_SIDE_LIMIT}x{IMAGE_SIDE_LIMIT} pixels (the limit for a texture)")
}

/// Decodes a PNG or JPEG of at most [`IMAGE_SIDE_LIMIT`] pixels a side, so a header that
/// declares a huge image is refused before anything is allocated for it.
fn decode_bounded(encoded: &[u8]) -> Result<image::RgbaImage, String> {
    let mut reader =
        image::ImageReader::new(std::io::Cursor::new(encoded)).with_guessed_format().map_err(|e| e.to_string())?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(IMAGE_SIDE_LIMIT);
    limits.max_image_height = Some(IMAGE_SIDE_LIMIT);
    // A 16-bit RGBA image of the largest size.
    limits.max_alloc = Some(u64::from(IMAGE_SIDE_LIMIT).pow(2) * 8);
    reader.limits(limits);
    let decoded = reader.decode().map_err(|e| match e {
        image::ImageError::Limits(_) => too_large_image(),
        other => other.to_string(),
    })?;
    // No copy when the image already is RGBA8.
    Ok(decoded.into_rgba8())
}
