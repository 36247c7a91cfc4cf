//! One glTF triangle primitive, in the steps [`crate::gltf_import`] takes it through: read and
//! check its vertex attributes, pose it (skinning or the node's transform), and append its
//! triangles to the scene, generating flat normals when it has none.

use std::path::Path;

use glam::{Mat3, Mat4, Vec2, Vec3};

use crate::error::SceneError;
use crate::model::Scene;

/// Which primitive of which file: what its errors name.
pub(crate) struct PrimitiveAt<'a> {
    pub(crate) path: &'a Path,
    pub(crate) mesh: usize,
    pub(crate) primitive: usize,
}

impl PrimitiveAt<'_> {
    /// The primitive's data is malformed in the way `what` says.
    pub(crate) fn bad(&self, what: String) -> SceneError {
        SceneError::BadPrimitive { path: self.path.to_path_buf(), mesh: self.mesh, primitive: self.primitive, what }
    }
}

/// A primitive's vertex attributes, every one of `positions.len()` entries.
pub(crate) struct Vertices {
    pub(crate) positions: Vec<Vec3>,
    pub(crate) normals: Option<Vec<Vec3>>,
    pub(crate) uvs: Vec<Vec2>,
    /// Three per triangle, each below the vertex count.
    pub(crate) indices: Vec<u32>,
}

/// Reads the primitive's positions, normals, first texture coordinates and indices (a
/// non-indexed primitive gets `0..n`, one without UVs gets zeros) and checks that they agree.
pub(crate) fn read_vertices(
    prim: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    at: &PrimitiveAt<'_>,
) -> Result<Vertices, SceneError> {
    let bad = |what| at.bad(what);
    let reader = prim.reader(|b| Some(&buffers[b.index()].0[..]));
    let positions: Vec<Vec3> =
        reader.read_positions().ok_or_else(|| bad("no POSITION attribute".into()))?.map(Vec3::from).collect();
    let vertex_count = positions.len();
    let normals: Option<Vec<Vec3>> = reader.read_normals().map(|n| n.map(Vec3::from).collect());
    let uvs: Vec<Vec2> = match reader.read_tex_coords(0) {
        Some(t) => t.into_f32().map(Vec2::from).collect(),
        None => vec![Vec2::ZERO; vertex_count],
    };
    let indices: Vec<u32> = match reader.read_indices() {
        Some(i) => i.into_u32().collect(),
        None => (0..vertex_count as u32).collect(),
    };
    if indices.len() % 3 != 0 {
        return Err(bad(format!("{} indices, not a multiple of 3", indices.len())));
    }
    if let Some(&index) = indices.iter().find(|&&i| i as usize >= vertex_count) {
        return Err(SceneError::IndexOutOfRange {
            path: at.path.to_path_buf(),
            mesh: at.mesh,
            primitive: at.primitive,
            index,
            vertex_count,
        });
    }
    if normals.as_ref().is_some_and(|n| n.len() != vertex_count) || uvs.len() != vertex_count {
        return Err(bad("attribute counts differ from the POSITION count".into()));
    }
    Ok(Vertices { positions, normals, uvs, indices })
}

/// Each vertex's skinning matrix (its joints' world matrices blended by its weights), when the
/// node has a skin (`joints`) and the primitive JOINTS_0 and WEIGHTS_0.
pub(crate) fn skinning_matrices(
    prim: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    joints: Option<&[Mat4]>,
    vertex_count: usize,
    at: &PrimitiveAt<'_>,
) -> Result<Option<Vec<Mat4>>, SceneError> {
    let bad = |what| at.bad(what);
    let reader = prim.reader(|b| Some(&buffers[b.index()].0[..]));
    let (Some(js), Some(j), Some(w)) = (joints, reader.read_joints(0), reader.read_weights(0)) else {
        return Ok(None);
    };
    let j: Vec<[u16; 4]> = j.into_u16().collect();
    let w: Vec<[f32; 4]> = w.into_f32().collect();
    if j.len() != vertex_count || w.len() != vertex_count {
        return Err(bad("JOINTS_0/WEIGHTS_0 counts differ from POSITION".into()));
    }
    let mut per_vertex = Vec::with_capacity(vertex_count);
    for (jv, wv) in j.iter().zip(&w) {
        let mut m = Mat4::ZERO;
        for k in 0..4 {
            let joint = *js
                .get(jv[k] as usize)
                .ok_or_else(|| bad(format!("joint index {} out of range ({} joints)", jv[k], js.len())))?;
            m += joint * wv[k];
        }
        per_vertex.push(m);
    }
    Ok(Some(per_vertex))
}

/// Moves positions and normals to world space: by each vertex's skinning matrix for a skinned
/// mesh (whose node transform the glTF spec says to ignore), else by the node's `world`.
pub(crate) fn pose(vertices: &mut Vertices, skinning: Option<&[Mat4]>, world: Mat4) {
    let normal_matrix = |m: Mat4| Mat3::from_mat4(m).inverse().transpose();
    match skinning {
        Some(ms) => {
            for (k, p) in vertices.positions.iter_mut().enumerate() {
                *p = ms[k].transform_point3(*p);
            }
            if let Some(ns) = vertices.normals.as_mut() {
                for (k, n) in ns.iter_mut().enumerate() {
                    *n = (normal_matrix(ms[k]) * *n).normalize_or_zero();
                }
            }
        }
        None => {
            for p in vertices.positions.iter_mut() {
                *p = world.transform_point3(*p);
            }
            if let Some(ns) = vertices.normals.as_mut() {
                let nm = normal_matrix(world);
                for n in ns.iter_mut() {
                    *n = (nm * *n).normalize_or_zero();
                }
            }
        }
    }
}

/// Appends the triangles with `material`, reversing the winding of a `mirrored` primitive so
/// that counter-clockwise stays front-facing; without normals each triangle gets its own three
/// vertices with the face normal.
pub(crate) fn append_triangles(s: &mut Scene, vertices: Vertices, mirrored: bool, material: u32) {
    let Vertices { positions, normals, uvs, indices } = vertices;
    let corner = |t: &[u32], k: usize| if mirrored { t[[0, 2, 1][k]] } else { t[k] };
    match normals {
        Some(ns) => {
            let base = s.positions.len() as u32;
            s.positions.extend_from_slice(&positions);
            s.normals.extend(ns);
            s.uvs.extend_from_slice(&uvs);
            for t in indices.chunks_exact(3) {
                s.triangles.push([0, 1, 2].map(|k| base + corner(t, k)));
                s.triangle_materials.push(material);
            }
        }
        None => {
            // Flat normals need one vertex per triangle corner.
            for t in indices.chunks_exact(3) {
                let c = [0, 1, 2].map(|k| corner(t, k) as usize);
                let [a, b, d] = c.map(|i| positions[i]);
                let n = (b - a).cross(d - a).normalize_or_zero();
                let base = s.positions.len() as u32;
                for &i in &c {
                    s.positions.push(positions[i]);
                    s.normals.push(n);
                    s.uvs.push(uvs[i]);
                }
                s.triangles.push([base, base + 1, base + 2]);
                s.triangle_materials.push(material);
            }
        }
    }
}
