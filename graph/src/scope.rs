//! A leaf: what a pass declares about the views it runs for and how it reads and writes
//! ([`Role`], [`ReadScope`], [`SlotAccess`]), shared by the builder, the schedule and the errors
//! without any of them importing another.

/// Which views a pass runs for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum Role {
    All,
    /// Views that are path traced in full.
    Sources,
    /// Views synthesised from their sources.
    Targets,
    /// One instance for the whole light field (placed where view 0 runs, never split): what
    /// writes a global resource ([`Graph::global_buffer`](crate::Graph::global_buffer),
    /// [`Graph::global_image`](crate::Graph::global_image)), e.g. a reduction over every view
    /// ([`PassBuilder::read_every_view_slot`](crate::PassBuilder::read_every_view_slot)).
    Global,
}

/// Where a read looks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadScope {
    /// The instance's own view, over the instance's own rows (pixel-local read).
    Own,
    /// The instance's own view, every row (e.g. a filter with a large footprint).
    OwnWhole,
    /// The instance's own view, over the instance's own rows and this many rows above and below
    /// them (clamped to the view): a filter of bounded reach. A row band then needs only the
    /// neighbouring bands' rows within reach, not their whole view.
    OwnHalo(u32),
    /// Every source view of the instance's (target) view, every row: a reprojection read.
    Sources,
    /// The previous frame's last version of the instance's own view, own rows.
    History,
    /// Every view of the light field, every row: what a global pass reduces over.
    EveryView,
}

/// How a pass touches a slot; a pass touches each family at most once in each way.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlotAccess {
    /// The own view's current version (over the own rows or the whole view).
    Read,
    /// Each source view's current version.
    SourceRead,
    /// Last frame's final version.
    HistoryRead,
    Write,
}

impl SlotAccess {
    pub(crate) fn of_read(scope: ReadScope) -> Self {
        match scope {
            ReadScope::Own | ReadScope::OwnWhole | ReadScope::OwnHalo(_) => SlotAccess::Read,
            ReadScope::Sources | ReadScope::EveryView => SlotAccess::SourceRead,
            ReadScope::History => SlotAccess::HistoryRead,
        }
    }
}

impl std::fmt::Display for SlotAccess {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SlotAccess::Read => "read",
            SlotAccess::SourceRead => "source read",
            SlotAccess::HistoryRead => "history read",
            SlotAccess::Write => "write",
        })
    }
}
