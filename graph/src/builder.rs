//! Declaring a render graph: typed per-view resource handles and passes with roles.
//!
//! A pass is declared once and instantiated for every view its [`Role`] selects. Reads and
//! writes go through handles; a write takes `&mut` and bumps the handle's per-view version, so
//! a later read sees the new version and the analyser can derive producer → consumer edges from
//! versions alone. Reading "the source view's" version of a resource ([`PassBuilder::read_sources`])
//! is how reprojection is declared: the δ-edges come from these reads, never from a list.

use std::marker::PhantomData;
use std::panic::Location;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::GraphError;
use crate::ids::{FamilyId, PassId, ViewId};
use crate::schedule::{Format, ResourceDesc};
pub use crate::scope::{ReadScope, Role, SlotAccess};

/// Which views are sources and which sources each target reprojects from.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewTopology {
    pub width: u32,
    pub height: u32,
    /// Per view: the sources it reads when it is a target; empty for a source view.
    pub sources_of: Vec<Vec<ViewId>>,
    pub is_source: Vec<bool>,
}

impl ViewTopology {
    /// `views` views of `width`×`height`, every one a source (nothing is reprojected).
    pub fn all_sources(views: u32, width: u32, height: u32) -> Self {
        ViewTopology {
            width,
            height,
            sources_of: vec![Vec::new(); views as usize],
            is_source: vec![true; views as usize],
        }
    }

    pub fn views(&self) -> u32 {
        self.is_source.len() as u32
    }

    pub fn in_role(&self, role: Role, v: ViewId) -> bool {
        match role {
            Role::All => true,
            Role::Sources => self.is_source[v.index()],
            Role::Targets => !self.is_source[v.index()],
            Role::Global => v == ViewId(0),
        }
    }
}

/// Marker for image handles.
#[derive(Debug)]
pub struct Image;
/// Marker for buffer handles.
#[derive(Debug)]
pub struct Buffer;

/// A per-view resource family: one resource per view, each with its own version counter.
/// Not `Clone`: the only way to get a newer version is to write through `&mut`.
#[derive(Debug)]
pub struct Handle<K> {
    graph: u64,
    pub(crate) family: FamilyId,
    pub(crate) versions: Vec<u32>,
    _kind: PhantomData<K>,
}

impl<K> Handle<K> {
    pub fn family(&self) -> FamilyId {
        self.family
    }

    /// Current version of this view's resource (0 = never written this frame).
    pub fn version(&self, v: ViewId) -> u32 {
        self.versions[v.index()]
    }
}

/// What a kernel keeps of its pass's declaration and binds through ([`PassInstance::read`](crate::PassInstance::read),
/// `sources`, `history_read`, `write`): one declared access of one pass, by
/// the pass and the access's index among its reads or writes. Only the pass builder makes them,
/// so a kernel binds only what its pass declared, and a misspelt slot does not compile.
macro_rules! slot_token {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub struct $name(PassId, u16);

        impl $name {
            /// The pass that declared the access.
            pub fn pass(self) -> PassId {
                self.0
            }

            /// Index of the declared access among the pass's reads (writes for a write).
            pub fn index(self) -> u16 {
                self.1
            }
        }
    };
}

slot_token!(
    /// A read of the instance's own view ([`PassBuilder::read_slot`], `read_whole_slot`, the
    /// read of `modify_slot`). Only a pass builder makes one, so a kernel cannot name a read
    /// its pass did not declare:
    ///
    /// ```compile_fail
    /// let forged = parallax_graph::ReadSlot(parallax_graph::PassId(0), 0);
    /// ```
    ReadSlot
);
slot_token!(
    /// A read of every source view of a target ([`PassBuilder::read_sources_slot`]).
    SourcesSlot
);
slot_token!(
    /// Last frame's final version ([`PassBuilder::read_history_slot`]).
    HistorySlot
);
slot_token!(
    /// A write ([`PassBuilder::write_slot`], the write of `modify_slot`).
    WriteSlot
);

#[derive(Clone, Debug)]
pub(crate) struct ReadDecl {
    pub family: FamilyId,
    /// Version per view at the time of the read.
    pub versions: Vec<u32>,
    pub scope: ReadScope,
    /// Name the kernel finds this read under: the resource's name (with the read's origin:
    /// own view, source i or history, which tells apart two reads of one resource).
    pub slot: String,
}

#[derive(Clone, Debug)]
pub(crate) struct WriteDecl {
    pub family: FamilyId,
    /// New version per view; only meaningful for views in the pass's role.
    pub versions: Vec<u32>,
    pub slot: String,
    /// Declared in place ([`PassBuilder::modify`]): the new version lives in the allocation of
    /// the version it replaces, which the same pass reads.
    pub in_place: bool,
}

#[derive(Clone, Debug)]
pub(crate) struct FamilyDecl {
    pub name: String,
    pub desc: ResourceDesc,
    pub imported: bool,
    /// Buffers rewritten at the start of every frame: these leading words, the rest zero.
    pub reset: Option<Vec<u32>>,
    /// Per view, the version gathered to device 0, and where `export` was called.
    pub exported: Option<(Vec<u32>, &'static Location<'static>)>,
    /// One resource for the whole light field rather than one per view.
    pub global: bool,
    pub at: &'static Location<'static>,
}

impl FamilyDecl {
    /// Whether the family's rows are the view's rows, so a pass split into row bands touches
    /// only its band of it (a view-sized image, a row buffer). Anything else (a buffer, an
    /// image of its own size, a global resource) is touched whole.
    pub(crate) fn banded(&self, view_height: u32) -> bool {
        !self.global
            && match self.desc {
                ResourceDesc::Image { height, .. } => height == view_height,
                ResourceDesc::RowBuffer { .. } => true,
                ResourceDesc::Buffer { .. } => false,
            }
    }
}

/// A declared pass, before instantiation.
#[derive(Clone, Debug)]
pub struct PassDecl {
    pub name: String,
    pub role: Role,
    /// The pass needs every row of its view at once and is never split into bands.
    pub whole_view: bool,
    pub side_effect: bool,
    /// Its kernel records consecutive instances as one op ([`PassBuilder::grouped`]).
    pub grouped: bool,
    pub at: &'static Location<'static>,
    pub(crate) reads: Vec<ReadDecl>,
    pub(crate) writes: Vec<WriteDecl>,
}

/// A render graph under declaration. `P` is what a pass carries to whoever executes it (the
/// backend's kernel type); planning never looks inside it, so `graph` stays free of GPU types
/// and a graph declared only to be planned uses `()`.
#[derive(Debug)]
pub struct Graph<P = ()> {
    id: u64,
    pub(crate) topology: ViewTopology,
    pub(crate) families: Vec<FamilyDecl>,
    pub(crate) passes: Vec<PassDecl>,
    /// Per pass (by `PassId`), the payload attached with [`PassBuilder::kernel`].
    pub(crate) payloads: Vec<Option<P>>,
    /// Mistakes found while declaring (a handle of another graph, a name given twice), in
    /// declaration order: the first is what [`crate::compile`] reports.
    pub(crate) refused: Vec<GraphError>,
}

static NEXT_GRAPH: AtomicU64 = AtomicU64::new(1);

impl Graph {
    /// A graph for planning only: its passes carry no kernels.
    pub fn new(topology: ViewTopology) -> Self {
        Graph::with_payload(topology)
    }
}

impl<P> Graph<P> {
    /// The name `handle`'s resource was declared with: the slot name kernels and readback find
    /// it by.
    pub fn name_of<K>(&self, handle: &Handle<K>) -> &str {
        &self.families[handle.family.index()].name
    }

    /// A graph whose passes carry a `P` each (attached with [`PassBuilder::kernel`]), e.g. the
    /// backend's kernels, so the executor never looks a kernel up by pass name.
    pub fn with_payload(topology: ViewTopology) -> Self {
        Graph {
            id: NEXT_GRAPH.fetch_add(1, Ordering::Relaxed),
            topology,
            families: Vec::new(),
            passes: Vec::new(),
            payloads: Vec::new(),
            refused: Vec::new(),
        }
    }

    pub fn topology(&self) -> &ViewTopology {
        &self.topology
    }

    pub fn passes(&self) -> &[PassDecl] {
        &self.passes
    }

    /// The payload (kernel) attached to `pass`, if any.
    pub fn payload(&self, pass: PassId) -> Option<&P> {
        self.payloads.get(pass.index()).and_then(Option::as_ref)
    }

    /// The first mistake found while declaring, which [`crate::compile`] reports.
    pub fn declaration_error(&self) -> Option<&GraphError> {
        self.refused.first()
    }

    /// Kernels, reports and slot lookups tell families apart by name, so a name is given once.
    #[track_caller]
    fn family<K>(&mut self, name: &str, desc: ResourceDesc) -> Handle<K> {
        self.declare_family(name, desc, false)
    }

    #[track_caller]
    fn declare_family<K>(&mut self, name: &str, desc: ResourceDesc, global: bool) -> Handle<K> {
        let at = Location::caller();
        if let Some(first) = self.families.iter().find(|f| f.name == name) {
            self.refused.push(GraphError::DuplicateResource { name: name.to_string(), first: first.at, at });
        }
        let family = FamilyId(self.families.len() as u32);
        self.families.push(FamilyDecl {
            name: name.to_string(),
            desc,
            imported: false,
            reset: None,
            exported: None,
            global,
            at,
        });
        // A global family has one resource, so one version counter.
        let counters = if global { 1 } else { self.topology.views() as usize };
        Handle { graph: self.id, family, versions: vec![0; counters], _kind: PhantomData }
    }

    /// One image per view, at the light field's resolution.
    #[track_caller]
    pub fn image(&mut self, name: &str, format: Format) -> Handle<Image> {
        let desc = ResourceDesc::Image { width: self.topology.width, height: self.topology.height, format };
        self.family(name, desc)
    }

    /// One image per view of its own size (not the view's), e.g. a 1×1 per-view reduction.
    /// Passes touch it whole, even when they are split into row bands.
    #[track_caller]
    pub fn image_sized(&mut self, name: &str, width: u32, height: u32, format: Format) -> Handle<Image> {
        self.family(name, ResourceDesc::Image { width, height, format })
    }

    /// One buffer for the whole light field: written only by a [`Role::Global`] pass, read
    /// whole by any pass. The planner keeps one instance where its writer runs and copies it to
    /// every other device that reads it.
    #[track_caller]
    pub fn global_buffer(&mut self, name: &str, bytes: u64) -> Handle<Buffer> {
        self.declare_family(name, ResourceDesc::Buffer { bytes }, true)
    }

    /// One image of its own size for the whole light field (see [`Self::global_buffer`]).
    #[track_caller]
    pub fn global_image(&mut self, name: &str, width: u32, height: u32, format: Format) -> Handle<Image> {
        self.declare_family(name, ResourceDesc::Image { width, height, format }, true)
    }

    /// Starts declaring a [`Role::Global`] pass: one instance for the whole light field.
    #[track_caller]
    pub fn global_pass(&mut self, name: &str) -> PassBuilder<'_, P> {
        self.pass(name, Role::Global)
    }

    /// One buffer per view.
    #[track_caller]
    pub fn buffer(&mut self, name: &str, bytes: u64) -> Handle<Buffer> {
        self.family(name, ResourceDesc::Buffer { bytes })
    }

    /// One buffer per view with `row_bytes` per image row, split into row bands like an image
    /// (see [`ResourceDesc::RowBuffer`]).
    #[track_caller]
    pub fn row_buffer(&mut self, name: &str, row_bytes: u64) -> Handle<Buffer> {
        self.family(name, ResourceDesc::RowBuffer { rows: self.topology.height, row_bytes })
    }

    /// Declares that version 0 of every view's resource arrives from outside the frame
    /// (uploaded or persistent), so reading it before any write is legal.
    pub fn import<K>(&mut self, handle: &Handle<K>) {
        self.families[handle.family.index()].imported = true;
    }

    /// Resets every view's buffer at the start of every frame, before any pass touches it: the
    /// first `header.len()` words set to `header`, the rest zeroed. Version 0 of the buffer is
    /// then the reset contents, which passes accumulate into (counters, indirect arguments,
    /// pixel lists) with [`PassBuilder::modify`].
    pub fn reset_each_frame(&mut self, handle: &Handle<Buffer>, header: Vec<u32>) {
        let family = &mut self.families[handle.family.index()];
        family.imported = true;
        family.reset = Some(header);
    }

    /// Marks the current version of every view's resource as a finished output: it keeps its
    /// producers alive and is gathered on device 0.
    #[track_caller]
    pub fn export<K>(&mut self, handle: &Handle<K>) {
        self.families[handle.family.index()].exported = Some((handle.versions.clone(), Location::caller()));
    }

    /// Starts declaring a pass that runs for every view of `role`.
    #[track_caller]
    pub fn pass(&mut self, name: &str, role: Role) -> PassBuilder<'_, P> {
        let decl = PassDecl {
            name: name.to_string(),
            role,
            whole_view: false,
            side_effect: false,
            grouped: false,
            at: Location::caller(),
            reads: Vec::new(),
            writes: Vec::new(),
        };
        // A builder borrows the graph until it is added, so the pass gets the next id.
        let id = PassId(self.passes.len() as u32);
        PassBuilder { graph: self, id, decl, payload: None, refused: None }
    }
}

/// Fluent pass declaration. Nothing is added to the graph until [`PassBuilder::add`].
#[must_use = "a pass is only added to the graph by .add()"]
pub struct PassBuilder<'g, P = ()> {
    graph: &'g mut Graph<P>,
    /// The id `add` gives the pass, which its slot tokens carry.
    id: PassId,
    decl: PassDecl,
    payload: Option<P>,
    /// The first mistake in this declaration, handed to the graph by `add`.
    refused: Option<GraphError>,
}

impl<P> PassBuilder<'_, P> {
    fn check<K>(&mut self, h: &Handle<K>) {
        if h.graph != self.graph.id {
            self.refuse(GraphError::ForeignHandle { pass: self.decl.name.clone(), family: h.family, at: self.decl.at });
        }
    }

    fn refuse(&mut self, error: GraphError) {
        self.refused.get_or_insert(error);
    }

    /// A kernel finds an access by its family and kind, so a pass declares each pair once.
    fn check_slot(&mut self, family: FamilyId, access: SlotAccess) {
        let taken = match access {
            SlotAccess::Write => self.decl.writes.iter().any(|w| w.family == family),
            _ => self.decl.reads.iter().any(|r| r.family == family && SlotAccess::of_read(r.scope) == access),
        };
        if taken {
            let slot = self.family_name(family);
            self.refuse(GraphError::DuplicateSlot { pass: self.decl.name.clone(), slot, access, at: self.decl.at });
        }
    }

    /// A global resource is one resource, so it has no source views and no other view to
    /// reduce over; a global pass has no view of its own, so it reads views only all at once.
    fn check_read_scope(&mut self, family: FamilyId, scope: ReadScope) {
        let global = self.graph.families[family.index()].global;
        let fits = match scope {
            ReadScope::Own | ReadScope::OwnWhole | ReadScope::OwnHalo(_) => global || self.decl.role != Role::Global,
            ReadScope::History => global == (self.decl.role == Role::Global),
            ReadScope::Sources => !global && self.decl.role != Role::Global,
            ReadScope::EveryView => !global && self.decl.role == Role::Global,
        };
        if !fits {
            let error = GraphError::ReadScope {
                pass: self.decl.name.clone(),
                resource: self.family_name(family),
                global,
                scope: format!("{scope:?}"),
                at: self.decl.at,
            };
            self.refuse(error);
        }
    }

    /// A global resource has one version per frame step, so one pass instance writes it: a
    /// global pass. A global pass has no view, so it writes only global resources.
    fn check_write_scope(&mut self, family: FamilyId) {
        let global = self.graph.families[family.index()].global;
        if global != (self.decl.role == Role::Global) {
            let error = GraphError::WriteScope {
                pass: self.decl.name.clone(),
                resource: self.family_name(family),
                global,
                at: self.decl.at,
            };
            self.refuse(error);
        }
    }

    fn family_name(&self, family: FamilyId) -> String {
        self.graph.families[family.index()].name.clone()
    }

    /// Declares a read; returns its index among the pass's reads (what its slot token names).
    fn push_read<K>(&mut self, h: &Handle<K>, scope: ReadScope) -> u16 {
        self.check(h);
        self.check_read_scope(h.family, scope);
        self.check_slot(h.family, SlotAccess::of_read(scope));
        let slot = self.family_name(h.family);
        self.decl.reads.push(ReadDecl { family: h.family, versions: h.versions.clone(), scope, slot });
        (self.decl.reads.len() - 1) as u16
    }

    /// Declares a write; returns its index among the pass's writes.
    fn push_write<K>(&mut self, h: &mut Handle<K>, in_place: bool) -> u16 {
        self.check(h);
        self.check_slot(h.family, SlotAccess::Write);
        self.check_write_scope(h.family);
        let topo = &self.graph.topology;
        for v in 0..topo.views() {
            if topo.in_role(self.decl.role, ViewId(v)) && (v as usize) < h.versions.len() {
                h.versions[v as usize] += 1;
            }
        }
        let slot = self.family_name(h.family);
        self.decl.writes.push(WriteDecl { family: h.family, versions: h.versions.clone(), slot, in_place });
        (self.decl.writes.len() - 1) as u16
    }

    /// Reads this view's current version over the instance's own rows; the kernel binds it
    /// through the returned slot.
    pub fn read_slot<K>(&mut self, h: &Handle<K>) -> ReadSlot {
        ReadSlot(self.id, self.push_read(h, ReadScope::Own))
    }

    /// Reads this view's current version, every row.
    pub fn read_whole_slot<K>(&mut self, h: &Handle<K>) -> ReadSlot {
        ReadSlot(self.id, self.push_read(h, ReadScope::OwnWhole))
    }

    /// Reads this view's current version over the instance's own rows and `rows` rows above and
    /// below them (clamped to the view): what a filter reaching `rows` rows away reads. A banded
    /// scheme copies only those rows of the neighbouring bands; `rows = 0` is [`Self::read_slot`].
    pub fn read_halo_slot<K>(&mut self, h: &Handle<K>, rows: u32) -> ReadSlot {
        let scope = if rows == 0 { ReadScope::Own } else { ReadScope::OwnHalo(rows) };
        ReadSlot(self.id, self.push_read(h, scope))
    }

    /// Reads the current version of the resource of each source of this (target) view: a
    /// reprojection read. Each such read yields a δ-edge source → target.
    pub fn read_sources_slot<K>(&mut self, h: &Handle<K>) -> SourcesSlot {
        SourcesSlot(self.id, self.push_read(h, ReadScope::Sources))
    }

    /// Reads every view's current version of a per-view resource, every row, from a
    /// [`Role::Global`] pass; the kernel sees view `i` as source `i` (`PassInstance::sources`).
    pub fn read_every_view_slot<K>(&mut self, h: &Handle<K>) -> SourcesSlot {
        SourcesSlot(self.id, self.push_read(h, ReadScope::EveryView))
    }

    /// Reads the previous frame's last version of this view's resource.
    pub fn read_history_slot<K>(&mut self, h: &Handle<K>) -> HistorySlot {
        HistorySlot(self.id, self.push_read(h, ReadScope::History))
    }

    /// Writes this view's resource over the instance's rows, making a new version in an
    /// allocation of its own (so passes still reading the old version are unaffected).
    pub fn write_slot<K>(&mut self, h: &mut Handle<K>) -> WriteSlot {
        WriteSlot(self.id, self.push_write(h, false))
    }

    /// Reads and writes this view's resource in place over the instance's rows: the pass reads
    /// the current version and leaves the next one in the same allocation. Only a pass whose
    /// every invocation reads exactly the texels it writes may declare this.
    pub fn modify_slot<K>(&mut self, h: &mut Handle<K>) -> (ReadSlot, WriteSlot) {
        (ReadSlot(self.id, self.push_read(h, ReadScope::Own)), WriteSlot(self.id, self.push_write(h, true)))
    }

    /// [`Self::read_slot`] for a pass whose kernel binds by position or none (planning).
    pub fn read<K>(mut self, h: &Handle<K>) -> Self {
        self.read_slot(h);
        self
    }

    /// [`Self::read_whole_slot`], chained.
    pub fn read_whole<K>(mut self, h: &Handle<K>) -> Self {
        self.read_whole_slot(h);
        self
    }

    /// [`Self::read_halo_slot`], chained.
    pub fn read_halo<K>(mut self, h: &Handle<K>, rows: u32) -> Self {
        self.read_halo_slot(h, rows);
        self
    }

    /// [`Self::read_sources_slot`], chained.
    pub fn read_sources<K>(mut self, h: &Handle<K>) -> Self {
        self.read_sources_slot(h);
        self
    }

    /// [`Self::read_history_slot`], chained.
    pub fn read_history<K>(mut self, h: &Handle<K>) -> Self {
        self.read_history_slot(h);
        self
    }

    /// [`Self::write_slot`], chained.
    pub fn write<K>(mut self, h: &mut Handle<K>) -> Self {
        self.write_slot(h);
        self
    }

    /// [`Self::modify_slot`], chained.
    pub fn modify<K>(mut self, h: &mut Handle<K>) -> Self {
        self.modify_slot(h);
        self
    }

    /// Reads an explicit version for every view. For graphs declared from data rather than
    /// through handles; versions that nothing writes are reported at compile time.
    pub fn read_version<K>(mut self, h: &Handle<K>, version: u32) -> Self {
        self.check(h);
        self.check_read_scope(h.family, ReadScope::Own);
        self.check_slot(h.family, SlotAccess::Read);
        let versions = vec![version; h.versions.len()];
        let slot = self.family_name(h.family);
        self.decl.reads.push(ReadDecl { family: h.family, versions, scope: ReadScope::Own, slot });
        self
    }

    /// Writes an explicit version for every view, without touching the handle. For graphs
    /// declared from data; conflicting writes are reported at compile time.
    pub fn write_version<K>(mut self, h: &Handle<K>, version: u32) -> Self {
        self.check(h);
        self.check_slot(h.family, SlotAccess::Write);
        self.check_write_scope(h.family);
        let versions = vec![version; h.versions.len()];
        let slot = self.family_name(h.family);
        self.decl.writes.push(WriteDecl { family: h.family, versions, slot, in_place: false });
        self
    }

    /// Attaches what executes this pass (the backend's kernel).
    pub fn kernel(mut self, payload: P) -> Self {
        self.payload = Some(payload);
        self
    }

    /// The pass needs its whole view at once (never split into row bands).
    pub fn whole_view(mut self) -> Self {
        self.decl.whole_view = true;
        self
    }

    /// Keeps the pass even if nothing exported depends on it.
    pub fn side_effect(mut self) -> Self {
        self.decl.side_effect = true;
        self
    }

    /// The pass's kernel records consecutive instances on a device as one op (the backend's
    /// `PassKernel::records_groups`, e.g. hole filling of many small targets). Ordering then
    /// keeps the copies out of its instances' outputs at the end of each run of them, whatever
    /// the compile options' batching, so a run is not cut into one op per instance
    /// (`CompileOptions`).
    pub fn grouped(mut self) -> Self {
        self.decl.grouped = true;
        self
    }

    /// Adds the pass to the graph.
    pub fn add(self) -> PassId {
        let id = self.id;
        if let Some(error) = self.refused {
            self.graph.refused.push(error);
        }
        self.graph.passes.push(self.decl);
        self.graph.payloads.push(self.payload);
        id
    }
}
