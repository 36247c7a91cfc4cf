//! Links: the cross-device channels of a plan, one per (producer device, consumer device) pair
//! that the plan copies over, each of a kind chosen when the executor is created
//! ([`link_kinds`]): the best the two devices offer, or the one `ExecOptions::link` asks for
//! (refused, before any work, where the pair cannot use it; nothing falls back silently).
//!
//! A copy goes producer resource → the link's staging buffer → consumer resource, two GPU
//! copies; the kinds differ in where the staging buffer lives and how the consumer learns
//! that a chunk is in it:
//! * `gpu` (logical devices of one GPU with opaque-fd memory and timeline semaphores): device
//!   memory exported by the producer and imported by the consumer (link_memory.rs), and the
//!   consumer's copy-in waits on the producer's progress timeline, imported into the consumer:
//!   the wait happens on the GPU, no host thread is involved;
//! * `shared` (one GPU, opaque-fd memory but no shareable semaphores, e.g. lavapipe): the same
//!   device memory, and the producer's signal forwarded by the host relay (relay.rs) to a
//!   "ready" timeline on the consumer;
//! * `relay` (anything else, e.g. two physical GPUs): host memory imported into both devices
//!   (VK_EXT_external_memory_host) and the relay's forwarded signal.
//!
//! * `remote` (the other device is another process's, crate::remote): host staging on this
//!   process's device, and the bytes moved by the executor's `RemoteTransport`; the consumer's
//!   ready timeline is raised once a chunk has arrived.
//!
//! A relayed link's ready timeline is raised once per chunk sent over it, in the order the
//! producer's segments complete them, so its values only increase and a consumer's copy-in waits
//! for the value of its chunk: one semaphore per pair instead of one per copy.

use std::collections::BTreeMap;
use std::sync::Arc;

use ash::vk;

use crate::device::Device;
use crate::error::{BackendError, Result};
use crate::plan::ExecutionPlan;
use crate::segments::Segment;

/// How a link moves data (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LinkKind {
    /// Shared device memory and a GPU-side wait on the producer's exported timeline.
    Gpu,
    /// Shared device memory and a host-forwarded signal.
    Shared,
    /// Host staging memory and a host-forwarded signal.
    Relay,
    /// To or from a device of another process: host staging on this process's end, the bytes
    /// sent through the executor's [`crate::RemoteTransport`] (never chosen by [`link_kinds`]).
    Remote,
}

impl LinkKind {
    /// Every kind two devices of this process can use, best first.
    pub const ALL: [LinkKind; 3] = [LinkKind::Gpu, LinkKind::Shared, LinkKind::Relay];

    /// The kind's name in logs, options and render.json.
    pub fn name(self) -> &'static str {
        match self {
            LinkKind::Gpu => "gpu",
            LinkKind::Shared => "shared",
            LinkKind::Relay => "relay",
            LinkKind::Remote => "remote",
        }
    }

    /// Whether a host relay thread forwards the link's signals between two devices of this
    /// process (a remote link's thread is its transport's, crate::remote).
    pub fn relayed(self) -> bool {
        matches!(self, LinkKind::Shared | LinkKind::Relay)
    }

    /// Why devices `producer` → `consumer` cannot use this kind, or `None` if they can.
    fn missing(self, producer: &Device, consumer: &Device) -> Option<String> {
        let lacks =
            |device: &Device, what: &str| format!("device {} ({}) lacks {what}", device.info.index, device.info.name);
        let one_gpu = || {
            (producer.uuids != consumer.uuids).then(|| {
                "the two devices are not one physical GPU under one driver (deviceUUID/driverUUID differ), which \
                 opaque-fd sharing needs"
                    .to_string()
            })
        };
        let memory_fd = || {
            [producer, consumer]
                .into_iter()
                .find(|d| d.external_memory_fd.is_none())
                .map(|d| lacks(d, "VK_KHR_external_memory_fd (exportable and importable transfer buffers)"))
        };
        match self {
            LinkKind::Gpu => one_gpu().or_else(memory_fd).or_else(|| {
                [producer, consumer]
                    .into_iter()
                    .find(|d| d.external_semaphore_fd.is_none())
                    .map(|d| lacks(d, "VK_KHR_external_semaphore_fd (exportable and importable timeline semaphores)"))
            }),
            LinkKind::Shared => one_gpu().or_else(memory_fd),
            LinkKind::Relay | LinkKind::Remote => [producer, consumer]
                .into_iter()
                .find(|d| d.external_memory_host.is_none())
                .map(|d| lacks(d, "VK_EXT_external_memory_host")),
        }
    }
}

impl std::str::FromStr for LinkKind {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        LinkKind::ALL.into_iter().find(|k| k.name() == s).ok_or_else(|| format!("unknown link kind `{s}`"))
    }
}

/// The kind of link of every ordered pair of devices: `kinds[from][to]` (`None` on the diagonal).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LinkKinds(pub Vec<Vec<Option<LinkKind>>>);

impl LinkKinds {
    /// The kind of the link `from` → `to`; `remote` where either is another process's device
    /// (a plan's device number past its own devices, crate::remote).
    pub fn of(&self, from: usize, to: usize) -> LinkKind {
        if from >= self.0.len() || to >= self.0.len() {
            return LinkKind::Remote;
        }
        self.0[from][to].expect("a link joins two devices")
    }
}

/// Chooses the kind of every pair of `devices`: `requested`, or with `None` the best each pair
/// offers. Fails with [`BackendError::LinkUnavailable`] for the first pair (by producer, then
/// consumer) that cannot use the requested kind.
pub fn link_kinds(devices: &[Arc<Device>], requested: Option<LinkKind>) -> Result<LinkKinds> {
    let mut kinds = vec![vec![None; devices.len()]; devices.len()];
    for (from, producer) in devices.iter().enumerate() {
        for (to, consumer) in devices.iter().enumerate().filter(|&(to, _)| to != from) {
            let kind = match requested {
                Some(kind) => match kind.missing(producer, consumer) {
                    None => kind,
                    Some(missing) => {
                        return Err(BackendError::LinkUnavailable { kind: kind.name(), from, to, missing });
                    }
                },
                None => {
                    let best = LinkKind::ALL.into_iter().find(|k| k.missing(producer, consumer).is_none());
                    best.ok_or_else(|| BackendError::LinkUnavailable {
                        kind: LinkKind::Relay.name(),
                        from,
                        to,
                        missing: LinkKind::Relay.missing(producer, consumer).unwrap_or_default(),
                    })?
                }
            };
            kinds[from][to] = Some(kind);
        }
    }
    Ok(LinkKinds(kinds))
}

/// One link of the running plan ([`crate::Executor::links`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LinkInfo {
    /// Its devices as the plan numbers them: the end of a `remote` link on another process is
    /// past the plan's own devices ([`crate::remote_device`] gives its number in the run).
    pub from: usize,
    pub to: usize,
    pub kind: LinkKind,
    /// Copy chunks sent over the link per frame.
    pub chunks_per_frame: u64,
    /// Bytes sent over the link per frame.
    pub bytes_per_frame: u64,
}

/// What one device submits each frame ([`crate::Executor::submissions`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeviceSubmissions {
    pub device: usize,
    /// Segments (one `VkSubmitInfo2` each, each signalling the progress timeline) a frame.
    pub submissions_per_frame: usize,
    /// Semaphore waits on other devices' links a frame (one per link a segment waits on: the
    /// waits of one segment on one link are merged into the largest value), and the space waits
    /// of copy-outs into host staging rings.
    pub cross_device_waits_per_frame: usize,
}

/// One link and the semaphore its consumer waits on (owned by the consumer's device state).
pub(crate) struct Link {
    pub(crate) from: usize,
    pub(crate) to: usize,
    pub(crate) kind: LinkKind,
    /// On the consumer: the ready timeline the relay raises, or for a `gpu` link the producer's
    /// progress timeline imported (null for a `remote` link whose consumer is another
    /// process's).
    pub(crate) ready: vk::Semaphore,
    /// On the producer, for a link whose staging is a ring that wraps (staging_ring.rs): the
    /// space timeline the relay raises after each of the consumer's copy-ins from the link.
    pub(crate) space: Option<vk::Semaphore>,
    /// Chunks sent over the link per frame: a ready (and space) timeline's step per frame.
    pub(crate) per_frame: u64,
    pub(crate) bytes_per_frame: u64,
}

/// Where one chunk travels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ChunkLink {
    /// Index of its link.
    pub(crate) link: usize,
    /// Its position among the link's chunks of a frame.
    pub(crate) position: u64,
    /// The producer's segment that completes it.
    pub(crate) segment: usize,
}

/// Where each chunk travels: the links of a plan as `(from, to, chunks per frame)`, and per copy
/// and chunk, its [`ChunkLink`].
#[derive(Debug, PartialEq, Eq)]
pub(crate) struct LinkOrder {
    pub(crate) links: Vec<(usize, usize, u64)>,
    pub(crate) chunks: Vec<Vec<ChunkLink>>,
}

/// Numbers each link's chunks in the order the producer's segments complete them
/// (`Segment::relays`), which is the order the relay signals them. `chunk_counts[c]` is the
/// number of chunks of copy `c`.
pub(crate) fn link_order(plan: &ExecutionPlan, segments: &[Vec<Segment>], chunk_counts: &[usize]) -> LinkOrder {
    let mut index: BTreeMap<(usize, usize), usize> = BTreeMap::new();
    let mut links: Vec<(usize, usize, u64)> = Vec::new();
    let unset = ChunkLink { link: usize::MAX, position: 0, segment: 0 };
    let mut chunks: Vec<Vec<ChunkLink>> = chunk_counts.iter().map(|&n| vec![unset; n]).collect();
    for (from, device) in segments.iter().enumerate() {
        for (segment, chunk) in device.iter().enumerate().flat_map(|(j, s)| s.relays.iter().map(move |c| (j, c))) {
            let to = plan.copy(chunk.copy).to.index();
            let link = *index.entry((from, to)).or_insert_with(|| {
                links.push((from, to, 0));
                links.len() - 1
            });
            chunks[chunk.copy.index()][chunk.index as usize] = ChunkLink { link, position: links[link].2, segment };
            links[link].2 += 1;
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
        let mut positions: Vec<u64> = order.chunks.iter().map(|c| c[0].position).collect();
        positions.sort_unstable();
        assert_eq!(positions, vec![0, 1, 2]);
        assert!(order.chunks.iter().all(|c| c.len() == 1 && c[0].link == 0));
        // One copy cut into chunks: their positions follow the chunks' order.
        let order = order_of(&copy_plan(256, 256).unwrap(), 256 * 1024);
        assert_eq!(order.links.len(), 1);
        let positions: Vec<u64> = order.chunks[0].iter().map(|c| c.position).collect();
        assert_eq!(positions, (0..order.links[0].2).collect::<Vec<_>>());
        assert!(positions.len() > 1, "the copy is chunked");
    }
}

#[cfg(test)]
mod kind_tests {
    use super::*;
    use crate::context::{Context, ContextDesc, DeviceSelection};
    use crate::instance::Validation;

    #[test]
    fn lavapipe_pairs_get_shared_by_default_relay_on_request_and_gpu_is_refused_naming_pair_and_extension() {
        let context =
            Context::new(&ContextDesc { selection: DeviceSelection::FakeDevices(2), validation: Validation::Core })
                .unwrap();
        let devices = &context.devices;
        let auto = link_kinds(devices, None).unwrap();
        assert_eq!((auto.of(0, 1), auto.of(1, 0)), (LinkKind::Shared, LinkKind::Shared));
        assert_eq!(link_kinds(devices, Some(LinkKind::Relay)).unwrap().of(0, 1), LinkKind::Relay);
        let refused = link_kinds(devices, Some(LinkKind::Gpu)).unwrap_err();
        assert_eq!(
            refused.to_string(),
            format!(
                "link kind `gpu` is unavailable from device 0 to device 1: device 0 ({}) lacks \
                 VK_KHR_external_semaphore_fd (exportable and importable timeline semaphores)",
                devices[0].info.name
            )
        );
    }

    #[test]
    fn link_kinds_parse_from_their_names_only() {
        for kind in LinkKind::ALL {
            assert_eq!(kind.name().parse::<LinkKind>(), Ok(kind));
        }
        assert_eq!("peer".parse::<LinkKind>(), Err("unknown link kind `peer`".to_string()));
    }
}
