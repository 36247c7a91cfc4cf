//! Building scenes in code: quads, boxes and spheres with one material each. Used by the
//! embedded default scene and by tests that need a scene with known properties.

use glam::{Quat, Vec2, Vec3};

use crate::camera::Camera;
use crate::model::{Material, Scene};

/// Appends primitives to a [`Scene`]; every primitive gets its own vertices (no sharing).
#[derive(Default)]
pub struct SceneBuilder {
    scene: Scene,
}

impl SceneBuilder {
    pub fn new(name: &str) -> Self {
        Self { scene: Scene { name: name.to_string(), ..Default::default() } }
    }

    /// Adds a material and returns its index.
    pub fn material(&mut self, m: Material) -> u32 {
        self.scene.materials.push(m);
        (self.scene.materials.len() - 1) as u32
    }

    pub fn camera(&mut self, c: Camera) -> &mut Self {
        self.scene.cameras.push(c);
        self
    }

    fn vertex(&mut self, p: Vec3, n: Vec3, uv: Vec2) -> u32 {
        self.scene.positions.push(p);
        self.scene.normals.push(n);
        self.scene.uvs.push(uv);
        (self.scene.positions.len() - 1) as u32
    }

    fn triangle(&mut self, idx: [u32; 3], material: u32) {
        self.scene.triangles.push(idx);
        self.scene.triangle_materials.push(material);
    }

    /// A parallelogram at `corner` spanned by `u` and `v`; it faces `u x v`.
    pub fn quad(&mut self, corner: Vec3, u: Vec3, v: Vec3, material: u32) -> &mut Self {
        let n = u.cross(v).normalize();
        let a = self.vertex(corner, n, Vec2::new(0.0, 1.0));
        let b = self.vertex(corner + u, n, Vec2::new(1.0, 1.0));
        let c = self.vertex(corner + u + v, n, Vec2::new(1.0, 0.0));
        let d = self.vertex(corner + v, n, Vec2::new(0.0, 0.0));
        self.triangle([a, b, c], material);
        self.triangle([a, c, d], material);
        self
    }

    /// A closed box with outward faces, rotated by `yaw` radians about +Y around its centre.
    pub fn cuboid(&mut self, center: Vec3, half: Vec3, yaw: f32, material: u32) -> &mut Self {
        let r = Quat::from_rotation_y(yaw);
        let (x, y, z) = (r * Vec3::X * half.x, r * Vec3::Y * half.y, r * Vec3::Z * half.z);
        let c = center;
        // Each face: corner, u, v with u x v pointing outwards.
        let faces = [
            (c - x - y + z, 2.0 * x, 2.0 * y),  // +z
            (c + x - y - z, -2.0 * x, 2.0 * y), // -z
            (c + x - y + z, -2.0 * z, 2.0 * y), // +x
            (c - x - y - z, 2.0 * z, 2.0 * y),  // -x
            (c - x + y + z, 2.0 * x, -2.0 * z), // +y
            (c - x - y - z, 2.0 * x, 2.0 * z),  // -y
        ];
        for (corner, u, v) in faces {
            self.quad(corner, u, v, material);
        }
        self
    }

    /// A closed icosphere with smooth normals; `subdivisions` 2 gives 320 triangles.
    pub fn sphere(&mut self, center: Vec3, radius: f32, subdivisions: u32, material: u32) -> &mut Self {
        let (verts, tris) = icosphere(subdivisions);
        let base = self.scene.positions.len() as u32;
        for v in &verts {
            let uv = Vec2::new(0.5 + v.z.atan2(v.x) / std::f32::consts::TAU, 0.5 - v.y.asin() / std::f32::consts::PI);
            self.vertex(center + *v * radius, *v, uv);
        }
        for t in tris {
            self.triangle(t.map(|i| base + i), material);
        }
        self
    }

    pub fn build(self) -> Scene {
        self.scene
    }
}

/// Unit icosphere: vertices on the sphere, counter-clockwise (outward-facing) triangles.
fn icosphere(subdivisions: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut verts: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, verts: &mut Vec<Vec3>| -> u32 {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                verts.push(((verts[a as usize] + verts[b as usize]) * 0.5).normalize());
                (verts.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(tris.len() * 4);
        for [a, b, c] in tris {
            let ab = mid(a, b, &mut verts);
            let bc = mid(b, c, &mut verts);
            let ca = mid(c, a, &mut verts);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    (verts, tris)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icosphere_faces_outwards() {
        let (v, t) = icosphere(1);
        assert_eq!(t.len(), 80);
        for [a, b, c] in t {
            let (a, b, c) = (v[a as usize], v[b as usize], v[c as usize]);
            assert!((b - a).cross(c - a).dot(a + b + c) > 0.0);
        }
    }

    #[test]
    fn cuboid_faces_outwards() {
        let mut b = SceneBuilder::new("box");
        let m = b.material(Material::diffuse("w", Vec3::ONE));
        b.cuboid(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.5, 1.0, 2.0), 0.3, m);
        let s = b.build();
        assert_eq!(s.triangles.len(), 12);
        for t in 0..12 {
            let [a, b2, c] = s.triangle_positions(t);
            let n = (b2 - a).cross(c - a);
            let centroid = (a + b2 + c) / 3.0;
            assert!(n.dot(centroid - Vec3::new(1.0, 2.0, 3.0)) > 0.0, "face {t} points inwards");
            assert!(n.normalize().dot(s.normals[s.triangles[t][0] as usize]) > 0.999);
        }
    }
}
