//! Reading glTF animations: the path of nodes from a root to the first perspective camera's
//! node, each with its rest TRS and the channels of any animation that target it (see
//! [`crate::animation`]), and every node with the channels of the file's first animation, which
//! poses skinned and node-animated meshes ([`crate::posing`]).

use std::path::Path;

use glam::{Mat4, Quat, Vec3};
use gltf::animation::util::ReadOutputs;

use crate::animation::{AnimatedNode, CameraAnimation, Interpolation, Track};
use crate::error::SceneError;
use crate::limits::MAX_COORDINATE;

/// The animation of camera node `camera_node` (yfov `yfov`), or None when nothing animates it
/// or a node above it.
pub(crate) fn camera_animation(
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    camera_node: usize,
    yfov: f32,
    path: &Path,
) -> Result<Option<CameraAnimation>, SceneError> {
    let chain = chain_from_root(doc, camera_node);
    let nodes: Vec<gltf::Node> = doc.nodes().collect();
    let mut animated: Vec<AnimatedNode> = chain.iter().map(|&i| rest_pose(&nodes[i])).collect();
    let mut duration = None;
    for animation in doc.animations() {
        let end = add_channels(&animation, buffers, path, &mut animated, |node| chain.iter().position(|&i| i == node))?;
        duration = latest(duration, end);
    }
    Ok(duration.map(|duration| CameraAnimation { nodes: animated, yfov, duration }))
}

/// Every node of the file (by index) with the tracks of the file's first animation, and the time
/// of its last keyframe; None when the file has no animation or its first moves no node (morph
/// weights only). glTF plays one animation at a time: Fox's Survey, Walk and Run drive the same
/// joints, and a viewer starts with the first.
pub(crate) fn first_animation_nodes(
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    path: &Path,
) -> Result<Option<(Vec<AnimatedNode>, f32)>, SceneError> {
    let Some(animation) = doc.animations().next() else { return Ok(None) };
    let mut nodes: Vec<AnimatedNode> = doc.nodes().map(|n| rest_pose(&n)).collect();
    let end = add_channels(&animation, buffers, path, &mut nodes, Some)?;
    Ok(end.map(|duration| (nodes, duration)))
}

/// Reads the channels of `animation` that target a node `slot` maps into `nodes` into that
/// node's tracks; returns the time of the last keyframe read, None when no channel moved a node.
fn add_channels(
    animation: &gltf::Animation,
    buffers: &[gltf::buffer::Data],
    path: &Path,
    nodes: &mut [AnimatedNode],
    slot: impl Fn(usize) -> Option<usize>,
) -> Result<Option<f32>, SceneError> {
    let mut duration = None;
    for (c, channel) in animation.channels().enumerate() {
        let node = channel.target().node().index();
        let Some(k) = slot(node) else { continue };
        let sampler = channel.sampler().index();
        let bad = |detail: String| SceneError::InvalidGltf {
            path: path.to_path_buf(),
            detail: format!("animation {} sampler {sampler} (channel {c}, node {node}): {detail}", animation.index()),
        };
        let end = add_track(&mut nodes[k], &channel, buffers, &bad)?;
        duration = latest(duration, end);
    }
    Ok(duration)
}

/// The later of two keyframe times, either of which may be missing.
fn latest(a: Option<f32>, b: Option<f32>) -> Option<f32> {
    a.into_iter().chain(b).reduce(f32::max)
}

/// The nodes from a root down to `node`, in that order.
fn chain_from_root(doc: &gltf::Document, node: usize) -> Vec<usize> {
    let mut parent = vec![None; doc.nodes().len()];
    for n in doc.nodes() {
        for c in n.children() {
            parent[c.index()] = Some(n.index());
        }
    }
    let mut chain = vec![node];
    while let Some(p) = parent[*chain.last().expect("never empty")] {
        if chain.contains(&p) || chain.len() > parent.len() {
            break; // a cycle: the node walk reports it
        }
        chain.push(p);
    }
    chain.reverse();
    chain
}

/// The node's own transform, without tracks.
fn rest_pose(node: &gltf::Node) -> AnimatedNode {
    match node.transform() {
        gltf::scene::Transform::Matrix { matrix } => AnimatedNode {
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: Vec3::ONE,
            matrix: Some(Mat4::from_cols_array_2d(&matrix)),
            translation_track: None,
            rotation_track: None,
            scale_track: None,
        },
        gltf::scene::Transform::Decomposed { translation, rotation, scale } => AnimatedNode {
            translation: Vec3::from(translation),
            rotation: Quat::from_array(rotation),
            scale: Vec3::from(scale),
            matrix: None,
            translation_track: None,
            rotation_track: None,
            scale_track: None,
        },
    }
}

/// Reads `channel` into the track of `node` it targets and checks it; returns its last keyframe
/// time, or None for a channel that does not move a node (morph weights).
fn add_track(
    node: &mut AnimatedNode,
    channel: &gltf::animation::Channel,
    buffers: &[gltf::buffer::Data],
    bad: &dyn Fn(String) -> SceneError,
) -> Result<Option<f32>, SceneError> {
    let interpolation = match channel.sampler().interpolation() {
        gltf::animation::Interpolation::Step => Interpolation::Step,
        gltf::animation::Interpolation::Linear => Interpolation::Linear,
        gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
    };
    let reader = channel.reader(|b| Some(&buffers[b.index()].0[..]));
    let times: Vec<f32> = reader.read_inputs().ok_or_else(|| bad("no keyframe times".into()))?.collect();
    if let Some(t) = times.iter().find(|t| !(0.0..=MAX_KEYFRAME_TIME).contains(*t)) {
        return Err(bad(format!("keyframe time {t:e} s is outside 0..={MAX_KEYFRAME_TIME:e} s")));
    }
    let well_formed = match reader.read_outputs() {
        Some(ReadOutputs::Translations(v)) => {
            let track = Track { times: times.clone(), values: v.map(Vec3::from).collect(), interpolation };
            check_values(&track.values, "translation", |p| p.is_finite() && p.abs().max_element() <= MAX_COORDINATE)
                .map_err(bad)?;
            let ok = track.is_well_formed();
            node.translation_track = Some(track);
            ok
        }
        Some(ReadOutputs::Rotations(v)) => {
            let values = v.into_f32().map(Quat::from_array).collect();
            let track = Track { times: times.clone(), values, interpolation };
            check_values(&track.values, "rotation", |q| q.is_finite() && q.length_squared() > 1e-12).map_err(bad)?;
            let ok = track.is_well_formed();
            node.rotation_track = Some(track);
            ok
        }
        Some(ReadOutputs::Scales(v)) => {
            let track = Track { times: times.clone(), values: v.map(Vec3::from).collect(), interpolation };
            check_values(&track.values, "scale", |s| s.is_finite() && s.abs().max_element() <= MAX_COORDINATE)
                .map_err(bad)?;
            let ok = track.is_well_formed();
            node.scale_track = Some(track);
            ok
        }
        // Morph weights do not move a node (Parallax imports no morph targets).
        Some(ReadOutputs::MorphTargetWeights(_)) => return Ok(None),
        None => return Err(bad("no output values".into())),
    };
    if !well_formed {
        return Err(bad("keyframe times are not finite and increasing, or do not match the values".into()));
    }
    if node.matrix.is_some() {
        return Err(bad("the node has a matrix, which glTF does not allow to animate".into()));
    }
    Ok(Some(*times.last().expect("well formed tracks have keyframes")))
}

/// The longest keyframe time an animation may have: 1e6 s (11 days).
pub const MAX_KEYFRAME_TIME: f32 = 1e6;

/// Every keyframe value is finite and within range (`ok`): a NaN or 1e30 would render black
/// frames while render.json reported an animation.
fn check_values<T: std::fmt::Debug>(values: &[T], what: &str, ok: impl Fn(&T) -> bool) -> Result<(), String> {
    match values.iter().position(|v| !ok(v)) {
        None => Ok(()),
        Some(i) => {
            Err(format!("{what} keyframe value {i} is {:?}: not finite, zero or beyond ±{MAX_COORDINATE:e}", values[i]))
        }
    }
}
