//! `--sources-per-set auto`: how many sources each multi-source set path traces, and where,
//! chosen by a predicted frame time.
//!
//! A source costs a view of path tracing; each target then reprojects from its nearest source
//! and path traces the pixels it misses (hole filling). More sources mean shorter baselines and
//! fewer holes. Per set, and within it per connected block of the layout (NELF's two eyes are
//! two blocks: a source in one eye sees little of what the other misses), the choice is the
//! number of sources k, placed as the medoids of a compact split of the block (what a numeric
//! `--sources-per-set` places), that minimises
//!
//!   cost(k) = k + HOLE_COST · Σ_targets missing(baseline to the nearest source)
//!
//! in views path traced, never fewer than one source per block.
//!
//! The prediction is geometric: it needs only the views' positions, so it is free, the same for
//! the same inputs, and `plan` (which has no scene) predicts what `render` runs, as every plan
//! depends only on the layout. What a target misses grows with the angle its baseline subtends
//! at the scene (disocclusions, and view-dependent shading beyond the reprojection tolerance);
//! for a scene of fixed depth that is linear in the baseline: missing(b) = HOLES_AT_SOURCE +
//! HOLES_PER_METRE · b, at most 1, the line through issue 27's measurements on Sponza (one H200,
//! focus 4 m): 0.4–0.8 % of a view next to its source (1 mm), 14–15 % at the other eye (62 mm).
//! A low-resolution first-hit pass would see the scene's depths and occluders, but would cost a
//! GPU pass before planning and make the plan depend on the camera. HOLE_COST, the cost of a
//! hole pixel in source pixels: 55 ms of hole filling for 6.5 Mpixel of holes against 9.5 ms for
//! a 1-Mpixel source at 1 spp on the same H200 (NELF, one source): 0.9.
//! With these, NELF on one device gets one source per eye (measured there: 125.85 ms against
//! 165.30 ms for one source and 142.59 ms for four).

use glam::DVec2;
use serde::Serialize;

use crate::assign::{AssignStrategy, assign};
use crate::error::PartitionError;
use crate::ids::ViewId;
use crate::lightfield::LightField;
use crate::source::medoid;

/// Predicted fraction of a target's pixels missing at zero baseline.
pub const HOLES_AT_SOURCE: f64 = 0.004;
/// Predicted growth of the missing fraction per metre of baseline.
pub const HOLES_PER_METRE: f64 = 2.3;
/// Cost of filling one hole pixel, in path-traced source pixels.
pub const HOLE_COST: f64 = 0.9;
/// Views closer than this many times the layout's smallest spacing are one block.
const BLOCK_LINK: f64 = 1.5;

/// The prediction for one set's sources (render.json and `plan --json`, `plan.sources_prediction`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SetPrediction {
    /// The set (its device under multi-source).
    pub set: u32,
    /// Sources chosen in the set.
    pub sources: u32,
    /// Connected blocks of the layout in the set (the fewest sources allowed).
    pub blocks: u32,
    /// Predicted mean missing fraction over the set's targets.
    pub predicted_missing: f64,
    /// Predicted cost of the set's sources and hole filling, in views path traced.
    pub predicted_cost_views: f64,
}

/// Predicted fraction of a target's pixels missing after reprojection from a source `baseline`
/// metres away.
pub fn predicted_missing(baseline: f64) -> f64 {
    (HOLES_AT_SOURCE + HOLES_PER_METRE * baseline).min(1.0)
}

/// `count` sources of `members`: the medoids of their compact split into `count` parts.
pub fn compact_sources(lf: &LightField, members: &[ViewId], count: u32) -> Result<Vec<ViewId>, PartitionError> {
    if count == 1 {
        return Ok(vec![medoid(members, |v| lf.position(v)).expect("a set or block is never empty")]);
    }
    let positions: Vec<DVec2> = members.iter().map(|&v| lf.position(v)).collect();
    let parts = assign(AssignStrategy::Compact, &positions, count)?;
    Ok(parts
        .sets
        .iter()
        .map(|part| {
            let views: Vec<ViewId> = part.iter().map(|local| members[local.index()]).collect();
            medoid(&views, |v| lf.position(v)).expect("parts are never empty when k <= members")
        })
        .collect())
}

/// Predicted cost of `members` with `sources`: the sources plus the hole filling of every
/// target from its nearest source, in views path traced; and the mean missing fraction.
fn predicted_cost(lf: &LightField, members: &[ViewId], sources: &[ViewId]) -> (f64, f64) {
    let missing: f64 = members
        .iter()
        .filter(|v| !sources.contains(v))
        .map(|&v| {
            let at = lf.position(v);
            let baseline = sources.iter().map(|&s| at.distance(lf.position(s))).fold(f64::INFINITY, f64::min);
            predicted_missing(baseline)
        })
        .sum();
    (sources.len() as f64 + HOLE_COST * missing, missing / members.len() as f64)
}

/// The connected blocks of the layout that `members` fall in (views closer than `BLOCK_LINK`
/// times the layout's smallest spacing to one another, transitively, over every view of the
/// layout, so a set of scattered views, as round-robin makes, is not split into many): the
/// members grouped by block, in order of their first member.
fn blocks(lf: &LightField, members: &[ViewId]) -> Vec<Vec<ViewId>> {
    let block_of = layout_blocks(lf);
    let mut blocks: Vec<(usize, Vec<ViewId>)> = Vec::new();
    for &v in members {
        match blocks.iter_mut().find(|(b, _)| *b == block_of[v.index()]) {
            Some((_, block)) => block.push(v),
            None => blocks.push((block_of[v.index()], vec![v])),
        }
    }
    blocks.into_iter().map(|(_, block)| block).collect()
}

/// The block of every view of the layout (all one block when the views coincide).
fn layout_blocks(lf: &LightField) -> Vec<usize> {
    let link = BLOCK_LINK * smallest_spacing(lf);
    let mut block_of: Vec<Option<usize>> = vec![None; lf.len()];
    let mut count = 0;
    for start in 0..lf.len() {
        if block_of[start].is_some() {
            continue;
        }
        block_of[start] = Some(count);
        let mut queue = vec![start];
        while let Some(i) = queue.pop() {
            let at = lf.positions[i];
            for (j, block) in block_of.iter_mut().enumerate() {
                if block.is_none() && at.distance(lf.positions[j]) <= link {
                    *block = Some(count);
                    queue.push(j);
                }
            }
        }
        count += 1;
    }
    block_of.into_iter().map(|b| b.expect("every view was reached")).collect()
}

/// The smallest distance between two distinct view positions of the layout (0 when they all
/// coincide: then every view is one block).
fn smallest_spacing(lf: &LightField) -> f64 {
    let mut smallest = f64::INFINITY;
    for (i, a) in lf.positions.iter().enumerate() {
        for b in &lf.positions[i + 1..] {
            let d = a.distance(*b);
            if d > 0.0 {
                smallest = smallest.min(d);
            }
        }
    }
    if smallest.is_finite() { smallest } else { 0.0 }
}

/// The sources of set `set` (its views `members`) that minimise the predicted cost, block by
/// block, and the prediction.
pub fn cheapest_sources(
    lf: &LightField,
    set: u32,
    members: &[ViewId],
) -> Result<(Vec<ViewId>, SetPrediction), PartitionError> {
    let blocks = blocks(lf, members);
    let mut sources = Vec::new();
    for block in &blocks {
        let mut best = (f64::INFINITY, Vec::new());
        for k in 1..=block.len() as u32 {
            // Each source costs a view: k alone above the best cost cannot win.
            if f64::from(k) >= best.0 {
                break;
            }
            let candidate = compact_sources(lf, block, k)?;
            let (cost, _) = predicted_cost(lf, block, &candidate);
            if cost < best.0 {
                best = (cost, candidate);
            }
        }
        sources.extend(best.1);
    }
    sources.sort();
    let prediction = predict(lf, set, members, &sources, blocks.len() as u32);
    Ok((sources, prediction))
}

/// The prediction for set `set` (views `members`) with `sources` and `blocks` blocks.
pub fn predict(lf: &LightField, set: u32, members: &[ViewId], sources: &[ViewId], blocks: u32) -> SetPrediction {
    let (cost, missing) = predicted_cost(lf, members, sources);
    SetPrediction { set, sources: sources.len() as u32, blocks, predicted_missing: missing, predicted_cost_views: cost }
}

/// The number of connected blocks among `members` (for the prediction of a numeric choice).
pub fn block_count(lf: &LightField, members: &[ViewId]) -> u32 {
    blocks(lf, members).len() as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lightfield::{LayoutSpec, Rig};

    fn all(lf: &LightField) -> Vec<ViewId> {
        lf.views().collect()
    }

    #[test]
    fn nelf_on_one_device_gets_one_source_per_eye_every_time() {
        let lf = LightField::new(LayoutSpec::Nelf, None, Some((64, 64)), Rig::default()).unwrap();
        let (sources, prediction) = cheapest_sources(&lf, 0, &all(&lf)).unwrap();
        assert_eq!(prediction.blocks, 2);
        assert_eq!(sources.len(), 2, "{sources:?}");
        let eye = |v: &ViewId| lf.position(*v).x > lf.centre().x;
        assert_ne!(eye(&sources[0]), eye(&sources[1]), "one in each eye: {sources:?}");
        assert_eq!(cheapest_sources(&lf, 0, &all(&lf)).unwrap(), (sources, prediction));
    }

    #[test]
    fn more_sources_than_blocks_only_where_the_holes_they_remove_cost_more() {
        // Views 1 mm apart: a second source pays off only over a long enough row.
        let short = LightField::new(LayoutSpec::Grid { cols: 8, rows: 1 }, Some(0.001), None, Rig::default()).unwrap();
        assert_eq!(cheapest_sources(&short, 0, &all(&short)).unwrap().0.len(), 1);
        let long = LightField::new(LayoutSpec::Multiscopic, None, None, Rig::default()).unwrap();
        let (sources, prediction) = cheapest_sources(&long, 0, &all(&long)).unwrap();
        assert!(sources.len() >= 2, "{sources:?}");
        let one = predict(&long, 0, &all(&long), &compact_sources(&long, &all(&long), 1).unwrap(), 1);
        assert!(prediction.predicted_cost_views < one.predicted_cost_views);
    }

    #[test]
    fn a_set_of_scattered_views_of_one_block_gets_one_source() {
        let lf = LightField::new(LayoutSpec::Grid { cols: 3, rows: 1 }, Some(0.001), None, Rig::default()).unwrap();
        let every_other = [ViewId(0), ViewId(2)];
        assert_eq!(block_count(&lf, &every_other), 1);
        assert_eq!(cheapest_sources(&lf, 0, &every_other).unwrap().0.len(), 1);
    }

    #[test]
    fn coincident_views_are_one_block() {
        let lf = LightField::new(LayoutSpec::Grid { cols: 3, rows: 1 }, Some(0.0), None, Rig::default()).unwrap();
        assert_eq!(block_count(&lf, &all(&lf)), 1);
        assert_eq!(cheapest_sources(&lf, 0, &all(&lf)).unwrap().0.len(), 1);
    }
}
