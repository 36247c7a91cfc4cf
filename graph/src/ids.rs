//! Small index newtypes, and [`Op`], the step of a device program they name. They are plain
//! numbers so that schedules stay plain data. A leaf: it imports nothing from the crate, so the
//! errors can name ids and ops without depending on the schedule.

use serde::Serialize;

macro_rules! id {
    ($(#[$doc:meta])* $name:ident, $prefix:literal) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
        pub struct $name(pub u32);

        impl $name {
            pub fn index(self) -> usize {
                self.0 as usize
            }
        }

        impl std::fmt::Display for $name {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, concat!($prefix, "{}"), self.0)
            }
        }
    };
}

id!(
    /// A view of the light field (row-major index over the grid).
    ViewId, "v"
);
id!(
    /// A GPU (physical or logical). Device 0 is the primary: finished views are gathered there.
    DeviceId, "gpu"
);
id!(
    /// One per-view resource: a (declared resource, view) pair.
    ResourceId, "r"
);
id!(
    /// One pass instance: a declared pass, for one view, over one row band, on one device.
    InstanceId, "p"
);
id!(
    /// One cross-device copy.
    CopyId, "c"
);
id!(
    /// A batch of cross-device copies moved as one transfer (`Schedule::batches`).
    BatchId, "b"
);
id!(
    /// A declared resource (the family of its per-view resources).
    FamilyId, "f"
);
id!(
    /// A declared pass (the template of its instances).
    PassId, "pass"
);
id!(
    /// Storage of one or more versions of a resource on one device.
    AllocId, "a"
);

impl AllocId {
    /// Not yet given storage (compile assigns every access one before it returns).
    pub const UNASSIGNED: AllocId = AllocId(u32::MAX);
}

/// A band of image rows `[y0, y1)`. Fine-grained schemes split views into bands; a whole view is
/// `[0, height)`. Buffers are one row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct Region {
    pub y0: u32,
    pub y1: u32,
}

impl Region {
    /// Rows `[y0, y1)`.
    pub fn new(y0: u32, y1: u32) -> Region {
        Region { y0, y1 }
    }

    pub fn rows(height: u32) -> Region {
        Region { y0: 0, y1: height }
    }

    pub fn len(self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }

    pub fn is_empty(self) -> bool {
        self.len() == 0
    }

    pub fn intersect(self, other: Region) -> Option<Region> {
        let r = Region { y0: self.y0.max(other.y0), y1: self.y1.min(other.y1) };
        (!r.is_empty()).then_some(r)
    }

    pub fn contains(self, other: Region) -> bool {
        self.y0 <= other.y0 && other.y1 <= self.y1
    }

    /// These rows and `rows` more above and below, within `[0, height)`.
    pub fn grown(self, rows: u32, height: u32) -> Region {
        Region { y0: self.y0.saturating_sub(rows), y1: self.y1.saturating_add(rows).min(height) }
    }

    /// Splits `[0, height)` into `n` bands whose heights differ by at most one row.
    pub fn bands(height: u32, n: u32) -> Vec<Region> {
        let n = n.max(1);
        (0..n)
            .map(|i| Region {
                y0: (height as u64 * i as u64 / n as u64) as u32,
                y1: (height as u64 * (i + 1) as u64 / n as u64) as u32,
            })
            .collect()
    }
}

impl std::fmt::Display for Region {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "rows {}..{}", self.y0, self.y1)
    }
}

/// One step of a device's program.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum Op {
    Pass(InstanceId),
    /// Producer side: device → shared host memory.
    CopyOut(CopyId),
    /// Producer side: tell the consumer the bytes are in host memory.
    Signal(CopyId),
    /// Consumer side: wait for the producer's signal.
    Wait(CopyId),
    /// Consumer side: shared host memory → device.
    CopyIn(CopyId),
}
