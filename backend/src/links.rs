//! Links: the cross-device channels of a plan, one per (producer device, consumer device) pair
//! that the plan copies over. Each link has one "ready" timeline on the consumer device; the
//! relay (relay.rs) raises it once per copy-out chunk sent over the link, in the order the
//! producer's segments complete them, so its values only increase, and a consumer's copy-in
//! waits for the value of its chunk. One semaphore per pair instead of one per copy: a
//! fine-grained plan has thousands of copies a frame but at most devices² links.

use std::collections::BTreeMap;

use ash::vk;

use crate::plan::ExecutionPlan;
use crate::segments::Segment;

/// How a link moves data. Only the host relay exists today: the producer's GPU copies into
/// host staging memory imported into both devices, a relay thread (relay.rs) forwards the
/// producer's signal, and the consumer's GPU copies out of the staging memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkKind {
    Relay,
}

impl LinkKind {
    /// The kind's name in logs and render.json.
    pub fn name(self) -> &'static str {
        match self {
            LinkKind::Relay => "relay",
        }
    }
}

/// One link of the running plan ([`crate::Executor::links`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LinkInfo {
    pub from: usize,
    pub to: usize,
    pub kind: LinkKind,
    /// Copy chunks sent over the link per frame.
    pub chunks_per_frame: u64,
}

/// One link and its ready timeline (owned by the consumer's device state).
pub(crate) struct Link {
    pub(crate) from: usize,
    pub(crate) to: usize,
    pub(crate) ready: vk::Semaphore,
    /// Chunks sent over the link per frame: the timeline's step per frame.
    pub(crate) per_frame: u64,
}

/// Where each chunk travels: the links of a plan as `(from, to, chunks per frame)`, and per copy
/// and chunk, the index of its link and its position among the link's chunks of a frame.
#[derive(Debug, PartialEq, Eq)]
pub(crate) struct LinkOrder {
    pub(crate) links: Vec<(usize, usize, u64)>,
    pub(crate) chunks: Vec<Vec<(usize, u64)>>,
}

/// Numbers each link's chunks in the order the producer's segments complete them
/// (`Segment::relays`), which is the order the relay signals them. `chunk_counts[c]` is the
/// number of chunks of copy `c`.
pub(crate) fn link_order(plan: &ExecutionPlan, segments: &[Vec<Segment>], chunk_counts: &[usize]) -> LinkOrder {
    let mut index: BTreeMap<(usize, usize), usize> = BTreeMap::new();
    let mut links: Vec<(usize, usize, u64)> = Vec::new();
    let mut chunks: Vec<Vec<(usize, u64)>> = chunk_counts.iter().map(|&n| vec![(usize::MAX, 0); n]).collect();
    for (from, device) in segments.iter().enumerate() {
        for chunk in device.iter().flat_map(|s| &s.relays) {
            let to = plan.copy(chunk.copy).to.index();
            let l = *index.entry((from, to)).or_insert_with(|| {
                links.push((from, to, 0));
                links.len() - 1
            });
            chunks[chunk.copy.index()][chunk.index as usize] = (l, links[l].2);
            links[l].2 += 1;
        }
    }
    LinkOrder { links, chunks }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::{copy_plan, gather_plan};
    use crate::segments::{chunks_of_copies, segment_devices};

    fn order_of(plan: &ExecutionPlan, chunk_bytes: u64) -> LinkOrder {
        let chunks = chunks_of_copies(plan, chunk_bytes);
        let segments = segment_devices(plan, &chunks, chunk_bytes, None, false);
        link_order(plan, &segments, &chunks.iter().map(Vec::len).collect::<Vec<_>>())
    }

    #[test]
    fn the_chunks_of_every_copy_between_two_devices_share_one_link_in_send_order() {
        // Three copies of one chunk each, device 0 → 1: one link, positions 0, 1, 2.
        let order = order_of(&gather_plan(3, 16, 16).unwrap(), 1 << 20);
        assert_eq!(order.links, vec![(0, 1, 3)]);
        let mut positions: Vec<u64> = order.chunks.iter().map(|c| c[0].1).collect();
        positions.sort_unstable();
        assert_eq!(positions, vec![0, 1, 2]);
        assert!(order.chunks.iter().all(|c| c.len() == 1 && c[0].0 == 0));
        // One copy cut into chunks: their positions follow the chunks' order.
        let order = order_of(&copy_plan(256, 256).unwrap(), 256 * 1024);
        assert_eq!(order.links.len(), 1);
        let positions: Vec<u64> = order.chunks[0].iter().map(|&(_, p)| p).collect();
        assert_eq!(positions, (0..order.links[0].2).collect::<Vec<_>>());
        assert!(positions.len() > 1, "the copy is chunked");
    }
}
