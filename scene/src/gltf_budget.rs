//! What a glTF file will cost once loaded, estimated before the work that costs it: a file of a
//! megabyte can instance one mesh twenty thousand times (the BVH build then asks for gigabytes)
//! or name one large image from many image entries.
//!
//! - triangles after instancing: the node tree is walked and every node's mesh counted from
//!   its accessors' declared counts, before any buffer is read;
//! - texture bytes after sharing: image entries that name one file (or one buffer view) are
//!   one texture, decoded once, and each distinct image's size comes from its PNG/JPEG header,
//!   before any is decoded.
//!
//! Both are checked against stated limits ([`MAX_TRIANGLES`], [`MAX_TEXTURE_BYTES`]) and, with
//! [`crate::LoadOptions::memory`], against the memory the process may still take.

use std::path::{Path, PathBuf};

use crate::error::SceneError;

/// Triangles a scene may have after instancing (vertex indices are 32-bit; loading and the BVH
/// build take about [`HOST_BYTES_PER_TRIANGLE`] each).
pub const MAX_TRIANGLES: u64 = 100_000_000;
/// Bytes of decoded textures (RGBA8, after sharing) a scene may have: each is also uploaded
/// whole to every device.
pub const MAX_TEXTURE_BYTES: u64 = 4 << 30;
/// Peak host bytes per triangle while loading, building the BVH and uploading the scene: 490
/// measured (one million triangles, `trace` with and without `--cpu`), with a margin.
pub const HOST_BYTES_PER_TRIANGLE: u64 = 640;

/// The memory a load may take, and what bounds it (for the message).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryLimit {
    pub bytes: u64,
    pub bound: &'static str,
}

/// Triangles the default scene (or the first) draws, each node's meshes counted once per
/// node that draws them. A node reached twice (a cycle or shared child, refused later) is
/// counted once.
pub fn triangles_after_instancing(doc: &gltf::Document) -> u64 {
    let nodes: Vec<gltf::Node> = doc.nodes().collect();
    let roots: Vec<usize> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().map(|n| n.index()).collect(),
        None => {
            let mut is_child = vec![false; nodes.len()];
            for c in nodes.iter().flat_map(|n| n.children()) {
                is_child[c.index()] = true;
            }
            (0..nodes.len()).filter(|&i| !is_child[i]).collect()
        }
    };
    let mut seen = vec![false; nodes.len()];
    let mut stack = roots;
    let mut triangles = 0u64;
    while let Some(i) = stack.pop() {
        if std::mem::replace(&mut seen[i], true) {
            continue;
        }
        if let Some(mesh) = nodes[i].mesh() {
            triangles = triangles.saturating_add(mesh_triangles(&mesh));
        }
        stack.extend(nodes[i].children().map(|c| c.index()));
    }
    triangles
}

/// Triangles of one mesh, from its accessors' declared counts.
fn mesh_triangles(mesh: &gltf::Mesh) -> u64 {
    mesh.primitives()
        .map(|p| {
            let corners = p.indices().or_else(|| p.get(&gltf::Semantic::Positions)).map_or(0, |a| a.count());
            corners as u64 / 3
        })
        .sum()
}

/// Where an image's bytes come from: entries with one source share one decoded texture.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum ImageSource {
    View(usize),
    File(PathBuf),
    /// Refused when decoded (`data:` URIs, URIs that cannot be resolved): never shared.
    Unreadable(usize),
}

/// The distinct sources of a file's images, and for each image entry the index of its source.
pub fn distinct_sources(sources: Vec<ImageSource>) -> (Vec<ImageSource>, Vec<u32>) {
    let mut distinct: Vec<ImageSource> = Vec::new();
    let mut index = std::collections::HashMap::new();
    let of_entry = sources
        .into_iter()
        .map(|s| {
            *index.entry(s.clone()).or_insert_with(|| {
                distinct.push(s);
                distinct.len() as u32 - 1
            })
        })
        .collect();
    (distinct, of_entry)
}

/// Width and height from a PNG or JPEG header, without decoding.
pub fn image_dimensions(reader: impl std::io::BufRead + std::io::Seek) -> Result<(u32, u32), String> {
    image::ImageReader::new(reader)
        .with_guessed_format()
        .map_err(|e| e.to_string())?
        .into_dimensions()
        .map_err(|e| e.to_string())
}

/// What loading a scene will take, checked against the limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoadEstimate {
    pub triangles: u64,
    /// Image entries and the distinct images they name.
    pub images: usize,
    pub distinct_images: usize,
    /// Decoded RGBA8 bytes of the distinct images.
    pub texture_bytes: u64,
    /// The largest distinct image's decoded bytes at up to 16-bit RGBA before its conversion to
    /// RGBA8 (decoding holds both).
    pub largest_decode_bytes: u64,
}

impl LoadEstimate {
    /// Refuses more triangles than [`MAX_TRIANGLES`]: before any buffer is read.
    pub fn check_triangles(triangles: u64, path: &Path) -> Result<(), SceneError> {
        if triangles > MAX_TRIANGLES {
            return Err(SceneError::TooLarge {
                path: path.to_path_buf(),
                what: format!("its node tree draws {triangles} triangles after instancing"),
                limit: format!("the {MAX_TRIANGLES} a scene may have"),
                fix: "instance its meshes fewer times or simplify them".into(),
            });
        }
        Ok(())
    }

    /// Peak host bytes of loading: the triangles' share and the textures with the largest
    /// decode in flight.
    pub fn host_bytes(&self) -> u64 {
        self.triangles
            .saturating_mul(HOST_BYTES_PER_TRIANGLE)
            .saturating_add(self.texture_bytes)
            .saturating_add(self.largest_decode_bytes)
    }

    /// Refuses textures beyond [`MAX_TEXTURE_BYTES`] and a load beyond `memory`: before any
    /// image is decoded.
    pub fn check(&self, path: &Path, memory: Option<MemoryLimit>) -> Result<(), SceneError> {
        let gib = |b: u64| format!("{:.1} GiB", b as f64 / f64::from(1 << 30));
        let textures = format!(
            "{} image entr{} naming {} distinct image(s) decode to {} of RGBA8 textures",
            self.images,
            if self.images == 1 { "y" } else { "ies" },
            self.distinct_images,
            gib(self.texture_bytes)
        );
        if self.texture_bytes > MAX_TEXTURE_BYTES {
            return Err(SceneError::TooLarge {
                path: path.to_path_buf(),
                what: textures,
                limit: format!("the {} a scene's textures may have", gib(MAX_TEXTURE_BYTES)),
                fix: "downscale its images or use fewer".into(),
            });
        }
        if let Some(memory) = memory
            && self.host_bytes() > memory.bytes
        {
            return Err(SceneError::TooLarge {
                path: path.to_path_buf(),
                what: format!(
                    "loading it needs about {} of host memory ({} triangles after instancing at {HOST_BYTES_PER_TRIANGLE} B \
                     each; {textures})",
                    gib(self.host_bytes()),
                    self.triangles
                ),
                limit: format!("the {} this process may still take ({})", gib(memory.bytes), memory.bound),
                fix: "simplify the scene or downscale its images, or run with more memory".into(),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_naming_one_source_share_it() {
        let a = ImageSource::File("a.png".into());
        let (distinct, of_entry) = distinct_sources(vec![
            a.clone(),
            ImageSource::View(3),
            a.clone(),
            ImageSource::Unreadable(3),
            ImageSource::View(3),
        ]);
        assert_eq!(distinct, [a, ImageSource::View(3), ImageSource::Unreadable(3)]);
        assert_eq!(of_entry, [0, 1, 0, 2, 1]);
    }

    #[test]
    fn estimates_beyond_the_limits_are_refused_with_the_numbers() {
        let path = Path::new("s.gltf");
        let err = LoadEstimate::check_triangles(240_000_000, path).unwrap_err().to_string();
        assert_eq!(
            err,
            "s.gltf: its node tree draws 240000000 triangles after instancing, more than the 100000000 a scene may \
             have: instance its meshes fewer times or simplify them"
        );
        let side = 16384u64;
        let eight = LoadEstimate {
            triangles: 1,
            images: 8,
            distinct_images: 8,
            texture_bytes: 8 * side * side * 4,
            largest_decode_bytes: side * side * 8,
        };
        assert_eq!(
            eight.check(path, None).unwrap_err().to_string(),
            "s.gltf: 8 image entries naming 8 distinct image(s) decode to 8.0 GiB of RGBA8 textures, more than the 4.0 \
             GiB a scene's textures may have: downscale its images or use fewer"
        );
        let shared = LoadEstimate { distinct_images: 1, texture_bytes: side * side * 4, ..eight };
        assert!(shared.check(path, None).is_ok());
        let limit = MemoryLimit { bytes: 2 << 30, bound: "RLIMIT_AS" };
        assert_eq!(
            shared.check(path, Some(limit)).unwrap_err().to_string(),
            "s.gltf: loading it needs about 3.0 GiB of host memory (1 triangles after instancing at 640 B each; 8 image \
             entries naming 1 distinct image(s) decode to 1.0 GiB of RGBA8 textures), more than the 2.0 GiB this \
             process may still take (RLIMIT_AS): simplify the scene or downscale its images, or run with more memory"
        );
    }
}
