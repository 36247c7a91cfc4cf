//! The compiled schedule: plain data, nothing GPU-specific. `backend/` builds a kernel plan and command
//! buffers from it; `validate()` checks every invariant the executor relies on; `dot` draws it.

use serde::Serialize;

pub use crate::ids::Op;
use crate::ids::{AllocId, CopyId, DeviceId, FamilyId, InstanceId, PassId, Region, ResourceId, ViewId};
use crate::op_order::OpOrder;
use crate::scope::Role;

/// Texel formats a pass can declare for a per-view image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum Format {
    Rgba32f,
    Rgba16f,
    Rg32f,
    R32f,
    R32u,
    Rgba8,
    /// 32-bit float depth: what a raster pass's depth attachment holds (1.0 = far). Kernels
    /// read it as a sampled image, never as a storage image (see the backend's pipeline.rs).
    Depth32f,
}

impl Format {
    pub fn bytes_per_texel(self) -> u64 {
        match self {
            Format::Rgba32f => 16,
            Format::Rgba16f | Format::Rg32f => 8,
            Format::R32f | Format::R32u | Format::Rgba8 | Format::Depth32f => 4,
        }
    }

    /// Whether the format is a depth format (a depth attachment, not a colour or storage image).
    pub fn is_depth(self) -> bool {
        self == Format::Depth32f
    }
}

/// Shape of a per-view resource. Images are addressed by row bands; a buffer is one row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum ResourceDesc {
    Image {
        width: u32,
        height: u32,
        format: Format,
    },
    Buffer {
        bytes: u64,
    },
    /// A buffer with one `row_bytes` section per image row, split into bands like an image:
    /// band `[y0, y1)` owns bytes `y0 * row_bytes .. y1 * row_bytes`. What a per-band pixel
    /// list (its counters first) needs, so a compaction pass and its consumer both split.
    RowBuffer {
        rows: u32,
        row_bytes: u64,
    },
}

impl ResourceDesc {
    pub fn rows(self) -> u32 {
        match self {
            ResourceDesc::Image { height, .. } => height,
            ResourceDesc::Buffer { .. } => 1,
            ResourceDesc::RowBuffer { rows, .. } => rows,
        }
    }

    pub fn row_bytes(self) -> u64 {
        match self {
            ResourceDesc::Image { width, format, .. } => width as u64 * format.bytes_per_texel(),
            ResourceDesc::Buffer { bytes } => bytes,
            ResourceDesc::RowBuffer { row_bytes, .. } => row_bytes,
        }
    }

    /// Whether the resource is an image (else a buffer reached by address).
    pub fn is_image(self) -> bool {
        matches!(self, ResourceDesc::Image { .. })
    }

    pub fn bytes(self, region: Region) -> u64 {
        region.len() as u64 * self.row_bytes()
    }

    pub fn full(self) -> Region {
        Region::rows(self.rows())
    }
}

/// One per-view resource.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ResourceInfo {
    pub name: String,
    pub family: FamilyId,
    pub view: ViewId,
    pub desc: ResourceDesc,
    /// The version that is a finished output, gathered to device 0 at the end of the frame.
    pub exported: Option<u32>,
    /// Read as "previous frame" by some pass: must persist across frames.
    pub history: bool,
    /// Number of versions written per frame.
    pub versions: u32,
    /// Rewritten at the start of every frame (`Graph::reset_each_frame`): these leading words,
    /// the rest zero.
    pub reset: Option<Vec<u32>>,
    /// One resource for the whole light field (`Graph::global_buffer`, `global_image`), listed
    /// as view 0's; written only by a `Role::Global` pass.
    pub global: bool,
}

/// Where an access of a pass instance comes from, as its kernel sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub enum Origin {
    /// The instance's own view.
    Own,
    /// Source `i` of the instance's (target) view, in `ViewTopology::sources_of` order.
    Source(u32),
    /// The instance's own view, last frame's final version.
    History,
}

/// A read or a write of one version of a resource over a row band, in one allocation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct Access {
    pub resource: ResourceId,
    pub version: u32,
    pub region: Region,
    /// Where the version lives on the instance's device.
    pub alloc: AllocId,
    pub origin: Origin,
    /// Index of the declared read or write (in `PassInfo::reads` / `writes`) this access
    /// instantiates: it names the kernel's slot.
    pub decl: u16,
    /// A write declared in place: it shares the allocation of the version it replaces.
    pub in_place: bool,
}

/// Storage for versions of one resource on one device. Versions that are alive at the same
/// time never share one; a version written in place shares the allocation of the version it
/// replaces. The previous half of a [`HistoryPair`] is an allocation that holds no version of
/// the frame (`versions` empty): only history reads see it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Allocation {
    pub resource: ResourceId,
    pub device: DeviceId,
    /// Versions stored here, in increasing order.
    pub versions: Vec<u32>,
}

/// A resource read as history on one device, double buffered: a frame writes its final version
/// into `current` and its history reads see last frame's final version in `previous`. The
/// executor swaps the two roles by frame parity (both command buffers are recorded once), so
/// the two must be distinct storage of one description on one device: `Schedule::validate()`
/// proves it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct HistoryPair {
    /// Holds this frame's final version (and whatever versions share its allocation).
    pub current: AllocId,
    /// Holds last frame's final version; nothing but history reads touches it.
    pub previous: AllocId,
}

/// A declared slot of a pass: the name its kernel looks it up by.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct SlotInfo {
    pub name: String,
    /// The family the slot reads or writes.
    pub family: FamilyId,
    /// Rows a read reaches above and below the instance's own rows (a halo read,
    /// `PassBuilder::read_halo_slot`); 0 for any other access.
    pub halo: u32,
}

/// What the schedule keeps of each declared pass.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct PassInfo {
    pub name: String,
    pub role: Role,
    /// Declared [`grouped`](crate::PassBuilder::grouped): copies out of a run of its instances
    /// wait for the run's end.
    pub grouped: bool,
    pub reads: Vec<SlotInfo>,
    pub writes: Vec<SlotInfo>,
}

/// A declared pass instantiated for one view, one row band, one device.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PassInstance {
    pub pass: PassId,
    pub name: String,
    pub view: ViewId,
    pub region: Region,
    pub device: DeviceId,
    pub reads: Vec<Access>,
    pub writes: Vec<Access>,
    /// Reads of the previous frame's last version (no edge inside the frame).
    pub history_reads: Vec<Access>,
}

/// Producer → consumer dependency between two instances through one access.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Edge {
    pub producer: InstanceId,
    pub consumer: InstanceId,
    pub access: Access,
}

/// A reprojection dependency δ(S, T): an instance owned by target view T reads a resource owned
/// by source view S ≠ T. Counted once per (source view, consuming instance).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct DeltaEdge {
    pub source: ViewId,
    pub target: ViewId,
    pub consumer: InstanceId,
}

/// Why a copy exists.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum CopyKind {
    /// A consumer on `to` reads what a producer on `from` wrote.
    Dependency,
    /// A finished view region travels to device 0.
    Gather,
}

/// One cross-device copy of one version of a resource over a row band, through host memory
/// visible to both devices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct CrossCopy {
    pub resource: ResourceId,
    pub version: u32,
    pub region: Region,
    pub from: DeviceId,
    pub to: DeviceId,
    /// The version's allocation on `from` and on `to`.
    pub src_alloc: AllocId,
    pub dst_alloc: AllocId,
    pub bytes: u64,
    pub kind: CopyKind,
}

impl CrossCopy {
    /// A finished view on its way to device 0 (Table 1's "transfer"), not an intermediate
    /// result another device reads.
    pub fn is_gather(&self) -> bool {
        self.kind == CopyKind::Gather
    }
}

/// Everything one device does in a frame, in submission order.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DeviceProgram {
    pub device: DeviceId,
    pub ops: Vec<Op>,
    /// Indices of the ops a memory barrier precedes, increasing: wherever an op reads what an
    /// op since the last barrier wrote or writes what one touched, and at the first op that
    /// touches memory (it follows the previous frame). Placed when the schedule is compiled,
    /// proven by `validate()`, recorded as they stand by the backend.
    pub barriers: Vec<u32>,
}

/// A pass dropped because nothing that is exported or side-effecting needs it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct CulledPass {
    pub name: String,
    pub view: ViewId,
}

/// Dependency copies from one device to another moved as one transfer.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct CopyBatch {
    pub from: DeviceId,
    pub to: DeviceId,
    /// In the producer's program order.
    pub copies: Vec<CopyId>,
    /// Their bytes together.
    pub bytes: u64,
}

/// The compiled frame: per-device programs plus everything needed to check and draw them.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Schedule {
    pub views: u32,
    /// Rows of every view (the bands of each pass instance tile `0..height`).
    pub height: u32,
    pub devices: Vec<DeviceProgram>,
    /// Declared passes by `PassId` (instances name them by `PassInstance::pass`).
    pub passes: Vec<PassInfo>,
    pub resources: Vec<ResourceInfo>,
    pub allocations: Vec<Allocation>,
    /// The double-buffered history allocations (both halves are in `allocations`).
    pub history: Vec<HistoryPair>,
    pub instances: Vec<PassInstance>,
    pub edges: Vec<Edge>,
    pub delta_edges: Vec<DeltaEdge>,
    pub copies: Vec<CrossCopy>,
    /// The dependency copies grouped into transfers, one per device pair and stage (batch.rs):
    /// what the backend moves as one.
    pub batches: Vec<CopyBatch>,
    pub culled: Vec<CulledPass>,
    /// How the ops of each program are ordered (the compile option and what it gave):
    /// `devices` holds that order, which is the order the backend submits.
    pub op_order: OpOrder,
}

impl Schedule {
    pub fn instance(&self, id: InstanceId) -> &PassInstance {
        &self.instances[id.index()]
    }

    pub fn resource(&self, id: ResourceId) -> &ResourceInfo {
        &self.resources[id.index()]
    }

    pub fn copy(&self, id: CopyId) -> &CrossCopy {
        &self.copies[id.index()]
    }

    pub fn allocation(&self, id: AllocId) -> &Allocation {
        &self.allocations[id.index()]
    }

    /// The history pair whose previous half is `alloc`, if any.
    pub fn history_pair_of_previous(&self, alloc: AllocId) -> Option<&HistoryPair> {
        self.history.iter().find(|p| p.previous == alloc)
    }

    /// Copies between devices before the final gather.
    pub fn dependency_copies(&self) -> impl Iterator<Item = &CrossCopy> {
        self.copies.iter().filter(|c| c.kind == CopyKind::Dependency)
    }

    pub fn gather_copies(&self) -> impl Iterator<Item = &CrossCopy> {
        self.copies.iter().filter(|c| c.kind == CopyKind::Gather)
    }

    /// Bytes moved between devices per frame, gathers included.
    pub fn bytes_per_frame(&self) -> u64 {
        self.copies.iter().map(|c| c.bytes).sum()
    }

    /// Rows that halo reads (`PassBuilder::read_halo_slot`) reach beyond their instances' own
    /// rows, summed over every instance and halo read of a frame, and their bytes: what a
    /// banded scheme reads of the neighbouring bands where it would otherwise read whole views.
    pub fn halo_reads(&self) -> HaloReads {
        let mut halo = HaloReads::default();
        for instance in &self.instances {
            let declared = &self.passes[instance.pass.index()].reads;
            // Only view-sized resources are split into bands; anything else is read whole anyway.
            let halo_reads = instance.reads.iter().filter(|r| {
                declared[usize::from(r.decl)].halo > 0 && self.resource(r.resource).desc.rows() == self.height
            });
            for read in halo_reads {
                let own = read.region.intersect(instance.region).map_or(0, Region::len);
                let rows = read.region.len() - own;
                halo.rows += u64::from(rows);
                halo.bytes += u64::from(rows) * self.resource(read.resource).desc.row_bytes();
            }
        }
        halo
    }
}

/// What halo reads reach beyond their own rows in one frame ([`Schedule::halo_reads`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct HaloReads {
    pub rows: u64,
    pub bytes: u64,
}
