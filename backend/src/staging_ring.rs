//! The bounded host staging of `relay` links: each link's copies take turns in a ring of a
//! stated size instead of each having bytes of its own. Pure data, no Vulkan.
//!
//! A copy's offset in the ring is fixed (its place in the link's send order decides it), so
//! recorded command buffers stay valid. A copy that reuses bytes of earlier copies of the same
//! frame must not overwrite them before the consumer has copied them in: the producer's segment
//! that copies it out first waits on the link's "space" timeline, which the relay raises after
//! each of the consumer's copy-ins from the link (in the consumer's segment order, so the
//! values increase: the value of a copy is its last chunk's place among the link's copy-ins in
//! that order). Earlier frames never share bytes with a frame: each frame-in-flight slot has
//! its own ring, and a slot is reused only after its frame retired.
//!
//! Those waits run from a producer to a consumer, against the copies' direction, so they can
//! close a cycle with the ready waits; [`fit_rings`] checks the submission order with them
//! ([`submission_order`]) and doubles the rings until there is none (at the latest when every
//! ring holds its whole link: no reuse, no space waits).

use crate::plan::CopyId;
use crate::segments::{Run, submission_order};

/// Alignment of each copy's region inside the staging buffer.
pub(crate) const STAGING_ALIGN: u64 = 256;

/// One copy sent over a ring link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct RingCopy {
    pub(crate) copy: CopyId,
    /// Its bytes in the ring (aligned).
    pub(crate) bytes: u64,
    /// The producer's segment that copies out its first chunk.
    pub(crate) producer_segment: usize,
    /// The space value that says its bytes are copied in: 1 + the place of its last chunk among
    /// the link's copy-in chunks of a frame, in the consumer's segment order.
    pub(crate) freed: u64,
    /// The consumer's segment that copies in that chunk.
    pub(crate) consumer_segment: usize,
}

/// A link whose staging is a ring: its devices and its copies in send order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct RingLink {
    pub(crate) link: usize,
    pub(crate) from: usize,
    pub(crate) to: usize,
    pub(crate) copies: Vec<RingCopy>,
}

impl RingLink {
    /// Bytes of every copy: the ring that never wraps.
    pub(crate) fn whole(&self) -> u64 {
        self.copies.iter().map(|c| c.bytes).sum()
    }

    /// Bytes of the largest copy: the smallest ring.
    pub(crate) fn largest(&self) -> u64 {
        self.copies.iter().map(|c| c.bytes).max().unwrap_or(0)
    }
}

/// "Producer segment `segment` of device `device` waits until the space timeline of `link`
/// reaches `value` (within the frame)"; `after` is the consumer's `(device, segment)` that
/// raises it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct SpaceWait {
    pub(crate) link: usize,
    pub(crate) device: usize,
    pub(crate) segment: usize,
    pub(crate) value: u64,
    pub(crate) after: (usize, usize),
}

/// The offsets of `ring`'s copies in a ring of `size` bytes (at least the largest copy), and the
/// waits of the copies that reuse bytes of earlier ones: copies follow one another and start
/// over at 0 where the next one would run past the end.
pub(crate) fn place(ring: &RingLink, size: u64) -> (Vec<u64>, Vec<SpaceWait>) {
    let mut offsets: Vec<u64> = Vec::with_capacity(ring.copies.len());
    let mut waits = Vec::new();
    let mut cursor = 0u64;
    for (i, copy) in ring.copies.iter().enumerate() {
        if cursor + copy.bytes > size {
            cursor = 0;
        }
        let range = cursor..cursor + copy.bytes;
        // The earlier copy among those it overwrites that is copied in last.
        let overwritten = ring.copies[..i]
            .iter()
            .zip(&offsets)
            .filter(|&(c, &o)| o < range.end && range.start < o + c.bytes)
            .map(|(c, _)| c)
            .max_by_key(|c| c.freed);
        if let Some(last) = overwritten {
            waits.push(SpaceWait {
                link: ring.link,
                device: ring.from,
                segment: copy.producer_segment,
                value: last.freed,
                after: (ring.to, last.consumer_segment),
            });
        }
        offsets.push(cursor);
        cursor = range.end;
    }
    (offsets, waits)
}

/// A link's ring as staging memory is laid out: its size and its copies' offsets.
pub(crate) struct RingLayout {
    pub(crate) link: usize,
    pub(crate) size: u64,
    pub(crate) offsets: Vec<(CopyId, u64)>,
}

/// Rings that fit together.
#[derive(Debug, PartialEq, Eq)]
pub(crate) struct FittedRings {
    /// Per ring (as given): its size, and its copies' offsets.
    pub(crate) sizes: Vec<u64>,
    pub(crate) offsets: Vec<Vec<u64>>,
    pub(crate) waits: Vec<SpaceWait>,
    /// The submission order with the space waits.
    pub(crate) order: Vec<Run>,
}

/// Sizes the rings: `budget` bytes over every ring and `slots` frame slots, shared evenly, but
/// each ring at least its largest copy and at most its whole link; then doubled while the space
/// waits with the ready waits (`ready_waits`, [`crate::segments::cross_device_waits`]) form a
/// cycle. `None` when even whole links do (the ready waits alone do).
pub(crate) fn fit_rings(
    rings: &[RingLink],
    budget: u64,
    slots: usize,
    ready_waits: &[Vec<Vec<(usize, usize)>>],
) -> Option<FittedRings> {
    let share = budget / (rings.len().max(1) as u64 * slots.max(1) as u64);
    let mut sizes: Vec<u64> = rings.iter().map(|r| share.max(r.largest()).min(r.whole())).collect();
    loop {
        let placed: Vec<(Vec<u64>, Vec<SpaceWait>)> = rings.iter().zip(&sizes).map(|(r, &s)| place(r, s)).collect();
        let mut waits = ready_waits.to_vec();
        for wait in placed.iter().flat_map(|(_, w)| w) {
            waits[wait.device][wait.segment].push(wait.after);
        }
        if let Some(order) = submission_order(&waits) {
            let (offsets, waits): (Vec<Vec<u64>>, Vec<Vec<SpaceWait>>) = placed.into_iter().unzip();
            return Some(FittedRings { sizes, offsets, waits: waits.concat(), order });
        }
        if rings.iter().zip(&sizes).all(|(r, &s)| s >= r.whole()) {
            return None;
        }
        for (size, ring) in sizes.iter_mut().zip(rings) {
            *size = size.saturating_mul(2).min(ring.whole());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn copy(c: u32, bytes: u64, producer_segment: usize, freed: u64, consumer_segment: usize) -> RingCopy {
        RingCopy { copy: CopyId(c), bytes, producer_segment, freed, consumer_segment }
    }

    #[test]
    fn copies_wrap_around_and_wait_for_the_last_copy_in_of_what_they_overwrite() {
        // Device 0 sends four copies of 100 bytes, one segment each; device 1 copies them in,
        // in order, one segment each.
        let ring = RingLink {
            link: 0,
            from: 0,
            to: 1,
            copies: (0..4).map(|i| copy(i, 100, i as usize, u64::from(i) + 1, i as usize)).collect(),
        };
        let (offsets, waits) = place(&ring, 250);
        assert_eq!(offsets, vec![0, 100, 0, 100]);
        let waits: Vec<(usize, u64, (usize, usize))> = waits.iter().map(|w| (w.segment, w.value, w.after)).collect();
        assert_eq!(waits, vec![(2, 1, (1, 0)), (3, 2, (1, 1))]);
        assert_eq!(place(&ring, ring.whole()).1, vec![], "a whole ring never waits");
    }

    /// The consumer copies in the second copy before the first, and its segment that does so
    /// waits for the second copy-out: in a ring of one copy, the second copy-out would wait for
    /// the first copy-in, which comes after that. The check sees the cycle and the ring grows.
    #[test]
    fn a_ring_whose_space_waits_close_a_cycle_grows_until_none_does() {
        let ring = RingLink { link: 0, from: 0, to: 1, copies: vec![copy(0, 64, 0, 2, 1), copy(1, 64, 1, 1, 0)] };
        // Device 1's segment 0 copies in copy 1 (sent by device 0's segment 1), its segment 1
        // copies in copy 0 (device 0's segment 0).
        let ready = vec![vec![vec![], vec![]], vec![vec![(0, 1)], vec![(0, 0)]]];
        let (_, waits) = place(&ring, 64);
        assert_eq!(waits.len(), 1);
        let mut with_space = ready.clone();
        with_space[0][1].push(waits[0].after);
        assert_eq!(submission_order(&with_space), None, "the one-copy ring deadlocks");
        let fitted = fit_rings(std::slice::from_ref(&ring), 64, 1, &ready).unwrap();
        assert_eq!(fitted.sizes, vec![128]);
        assert_eq!((fitted.offsets, fitted.waits), (vec![vec![0, 64]], vec![]));
        // Where the order allows it, the budget's ring stays and waits.
        let forward = RingLink { link: 0, from: 0, to: 1, copies: vec![copy(0, 64, 0, 1, 0), copy(1, 64, 1, 2, 1)] };
        let ready = vec![vec![vec![], vec![]], vec![vec![(0, 0)], vec![(0, 1)]]];
        let fitted = fit_rings(&[forward], 64, 1, &ready).unwrap();
        assert_eq!((fitted.sizes, fitted.offsets), (vec![64], vec![vec![0, 0]]));
        assert_eq!(fitted.waits.len(), 1);
    }

    #[test]
    fn the_budget_is_shared_over_rings_and_slots_within_each_ring_s_bounds() {
        // Eight copies, one producer and one consumer segment each, in order.
        let ring = |link: usize, bytes: u64| RingLink {
            link,
            from: 0,
            to: 1,
            copies: (0..8).map(|i| copy(i, bytes, i as usize, u64::from(i) + 1, i as usize)).collect(),
        };
        let ready = vec![vec![vec![]; 8], (0..8).map(|i| vec![(0, i)]).collect()];
        // 4 KiB over two rings and two slots: 1 KiB each; a ring of 512-byte copies holds two.
        let fitted = fit_rings(&[ring(0, 512), ring(1, 512)], 4096, 2, &ready).unwrap();
        assert_eq!(fitted.sizes, vec![1024, 1024]);
        // Never below the largest copy, never above the whole link.
        let fitted = fit_rings(&[ring(0, 2048), ring(1, 16)], 4096, 2, &ready).unwrap();
        assert_eq!(fitted.sizes, vec![2048, 128]);
    }
}
