//! Compiling a declared graph: cull, instantiate per view and band, derive edges and δ-edges
//! from versions, order deterministically, then lower to per-device programs (`lower.rs`).
//!
//! Everything here is a pure function of the graph and the placement, so the same input always
//! gives the same schedule, byte for byte.

use std::cmp::Reverse;
use std::collections::{BTreeMap, BTreeSet, BinaryHeap, HashMap};

use crate::batch::batch_copies;
use crate::builder::{Graph, PassDecl};
use crate::error::GraphError;
use crate::ids::{AllocId, DeviceId, FamilyId, InstanceId, PassId, Region, ResourceId, ViewId};
use crate::lower::lower;
use crate::op_order::OpOrder;
use crate::order::{CompileOptions, order_programs};
use crate::proven::ProvenSchedule;
use crate::schedule::{
    Access, CulledPass, DeltaEdge, Edge, Origin, PassInfo, PassInstance, ResourceDesc, ResourceInfo, Schedule, SlotInfo,
};
use crate::scope::{ReadScope, Role};
use crate::storage::assign_storage;

/// What a placement may know about a pass.
#[derive(Clone, Copy, Debug)]
pub struct PassPlacementInfo<'a> {
    pub name: &'a str,
    pub role: Role,
    /// False when the pass must see its whole view at once (declared whole_view, or it touches a
    /// buffer pixel-locally, which has no rows to split).
    pub splittable: bool,
}

/// Decides where each pass instance runs. Implemented by the partitioning schemes.
pub trait Placement {
    fn devices(&self) -> u32;
    /// One `(device, rows)` per instance of `pass` for view `view`; the bands must tile
    /// `[0, height)` without overlap.
    fn place(&self, pass: PassPlacementInfo<'_>, view: ViewId, height: u32) -> Vec<(DeviceId, Region)>;
}

/// Compiles `graph` under `placement` into a schedule, with the default options (small copies
/// batched as the backend's default chunk size defines them, [`CompileOptions`]).
pub fn compile<P>(graph: &Graph<P>, placement: &dyn Placement) -> Result<ProvenSchedule, GraphError> {
    compile_with(graph, placement, &CompileOptions::default())
}

/// Compiles `graph` under `placement` into a schedule, its programs ordered by `options`, and
/// proves it (`Schedule::validate`): the one check of the schedule before the backend runs it.
pub fn compile_with<P>(
    graph: &Graph<P>,
    placement: &dyn Placement,
    options: &CompileOptions,
) -> Result<ProvenSchedule, GraphError> {
    if let Some(error) = graph.declaration_error() {
        return Err(error.clone());
    }
    let views = graph.topology.views();
    let writers = writer_map(graph)?;
    let needed = cull(graph, &writers)?;
    let resources = resource_infos(graph, &writers);
    // Resources are numbered family by family, a view's after another: a per-view family has
    // one per view, a global family one (its view 0).
    let first: Vec<u32> = graph
        .families
        .iter()
        .scan(0, |next, fam| {
            let first = *next;
            *next += if fam.global { 1 } else { views };
            Some(first)
        })
        .collect();
    let rid = |f: FamilyId, v: ViewId| ResourceId(first[f.index()] + home(graph, f, v).0);

    let mut instances = Vec::new();
    let mut culled = Vec::new();
    for (p, decl) in graph.passes.iter().enumerate() {
        for v in (0..views).map(ViewId) {
            if !graph.topology.in_role(decl.role, v) {
                continue;
            }
            if !needed.contains(&(p as u32, v.0)) {
                culled.push(CulledPass { name: decl.name.clone(), view: v });
                continue;
            }
            let info = PassPlacementInfo { name: &decl.name, role: decl.role, splittable: splittable(graph, decl) };
            for (device, region) in placement.place(info, v, graph.topology.height) {
                instances.push(instantiate(graph, &writers, decl, PassId(p as u32), v, device, region, &rid));
            }
        }
    }

    let edges = derive_edges(graph, &instances, &resources)?;
    let delta_edges = delta_edges(graph, &instances, &resources);
    let order = topological_order(&instances, &edges)?;
    let (devices, mut copies) = lower(placement.devices(), &instances, &edges, &resources, &order);
    let (allocations, history) = assign_storage(&mut instances, &mut copies, &order);
    let passes = pass_infos(graph);
    let mut schedule = Schedule {
        views,
        height: graph.topology.height,
        devices,
        passes,
        resources,
        allocations,
        history,
        instances,
        edges,
        delta_edges,
        copies,
        batches: Vec::new(),
        culled,
        op_order: OpOrder::default(),
    };
    order_programs(&mut schedule, options.batching);
    schedule.batches = batch_copies(&schedule);
    crate::barriers::place_all(&mut schedule);
    schedule.proven().map_err(GraphError::Unsound)
}

/// Ordered, so the versions of one (family, view) are a range: `last_version` is a lookup, not a
/// scan of every writer (which made compiling the fine schemes quadratic in the views).
type WriterMap = BTreeMap<(FamilyId, ViewId, u32), usize>;

/// (family, view, version) → declaring pass. Catches two passes writing one version.
fn writer_map<P>(graph: &Graph<P>) -> Result<WriterMap, GraphError> {
    let mut writers = WriterMap::new();
    for (p, decl) in graph.passes.iter().enumerate() {
        for w in &decl.writes {
            for v in (0..graph.topology.views()).map(ViewId) {
                if !graph.topology.in_role(decl.role, v) {
                    continue;
                }
                let key = (w.family, v, w.versions[v.index()]);
                if let Some(&first) = writers.get(&key) {
                    return Err(GraphError::DoubleWrite {
                        resource: graph.families[w.family.index()].name.clone(),
                        view: v,
                        version: key.2,
                        first: graph.passes[first].name.clone(),
                        second: decl.name.clone(),
                        at: decl.at,
                    });
                }
                writers.insert(key, p);
            }
        }
    }
    Ok(writers)
}

/// Last version of a (family, view) written this frame; what a history read sees next frame.
fn last_version(writers: &WriterMap, family: FamilyId, view: ViewId) -> u32 {
    writers.range((family, view, 0)..=(family, view, u32::MAX)).next_back().map_or(0, |(k, _)| k.2)
}

/// The view whose resource of `family` stands for view `v`: `v` itself, or view 0 for a global
/// family (its only resource).
fn home<P>(graph: &Graph<P>, family: FamilyId, v: ViewId) -> ViewId {
    if graph.families[family.index()].global { ViewId(0) } else { v }
}

/// The (family, view, version) triples one declared read touches for view `v`.
fn read_targets<P>(
    graph: &Graph<P>,
    writers: &WriterMap,
    scope: ReadScope,
    family: FamilyId,
    versions: &[u32],
    v: ViewId,
) -> Vec<(FamilyId, ViewId, u32)> {
    match scope {
        ReadScope::Own | ReadScope::OwnWhole | ReadScope::OwnHalo(_) => {
            let at = home(graph, family, v);
            vec![(family, at, versions[at.index()])]
        }
        ReadScope::Sources => {
            graph.topology.sources_of[v.index()].iter().map(|&s| (family, s, versions[s.index()])).collect()
        }
        ReadScope::EveryView => {
            (0..graph.topology.views()).map(|u| (family, ViewId(u), versions[u as usize])).collect()
        }
        ReadScope::History => {
            let at = home(graph, family, v);
            vec![(family, at, last_version(writers, family, at))]
        }
    }
}

/// The declared passes' names and slots, by `PassId`.
fn pass_infos<P>(graph: &Graph<P>) -> Vec<PassInfo> {
    graph
        .passes
        .iter()
        .map(|decl| PassInfo {
            name: decl.name.clone(),
            role: decl.role,
            grouped: decl.grouped,
            reads: decl
                .reads
                .iter()
                .map(|r| {
                    let halo = if let ReadScope::OwnHalo(rows) = r.scope { rows } else { 0 };
                    SlotInfo { name: r.slot.clone(), family: r.family, halo }
                })
                .collect(),
            writes: decl.writes.iter().map(|w| SlotInfo { name: w.slot.clone(), family: w.family, halo: 0 }).collect(),
        })
        .collect()
}

/// Keeps what exported resources and side-effect passes need; returns the needed (pass, view).
fn cull<P>(graph: &Graph<P>, writers: &WriterMap) -> Result<BTreeSet<(u32, u32)>, GraphError> {
    let mut stack: Vec<(u32, u32)> = Vec::new();
    for (f, fam) in graph.families.iter().enumerate() {
        if let Some((versions, at)) = &fam.exported {
            for (v, &version) in versions.iter().enumerate() {
                match writers.get(&(FamilyId(f as u32), ViewId(v as u32), version)) {
                    Some(&p) => stack.push((p as u32, v as u32)),
                    None if version == 0 && fam.imported => {}
                    None => {
                        return Err(GraphError::ExportOfUnwritten {
                            resource: fam.name.clone(),
                            view: ViewId(v as u32),
                            at,
                        });
                    }
                }
            }
        }
    }
    for (p, decl) in graph.passes.iter().enumerate().filter(|(_, d)| d.side_effect) {
        for v in (0..graph.topology.views()).filter(|&v| graph.topology.in_role(decl.role, ViewId(v))) {
            stack.push((p as u32, v));
        }
    }
    if stack.is_empty() {
        return Err(GraphError::NoRoots);
    }
    let mut needed = BTreeSet::new();
    while let Some((p, v)) = stack.pop() {
        if !needed.insert((p, v)) {
            continue;
        }
        let decl = &graph.passes[p as usize];
        for r in &decl.reads {
            for (family, u, version) in read_targets(graph, writers, r.scope, r.family, &r.versions, ViewId(v)) {
                match writers.get(&(family, u, version)) {
                    Some(&w) => stack.push((w as u32, u.0)),
                    None if version == 0
                        && (graph.families[family.index()].imported || r.scope == ReadScope::History) => {}
                    None => {
                        return Err(GraphError::ReadOfUnwritten {
                            pass: decl.name.clone(),
                            resource: graph.families[family.index()].name.clone(),
                            view: u,
                            version,
                            at: decl.at,
                        });
                    }
                }
            }
        }
    }
    Ok(needed)
}

/// A pass splits into row bands unless it writes something touched whole (one writer per
/// version), or reads a per-view buffer pixel-locally (which has no rows to split). Reading a
/// global resource or an image of its own size is a whole read from every band.
fn splittable<P>(graph: &Graph<P>, decl: &PassDecl) -> bool {
    let height = graph.topology.height;
    let whole = |f: FamilyId| !graph.families[f.index()].banded(height);
    let view_buffer = |f: FamilyId| {
        let fam = &graph.families[f.index()];
        !fam.global && matches!(fam.desc, ResourceDesc::Buffer { .. })
    };
    !decl.whole_view
        && decl.role != Role::Global
        && !decl.writes.iter().any(|w| whole(w.family))
        && !decl.reads.iter().any(|r| {
            matches!(r.scope, ReadScope::Own | ReadScope::OwnHalo(_) | ReadScope::History) && view_buffer(r.family)
        })
}

fn resource_infos<P>(graph: &Graph<P>, writers: &WriterMap) -> Vec<ResourceInfo> {
    let history: BTreeSet<FamilyId> = graph
        .passes
        .iter()
        .flat_map(|p| p.reads.iter().filter(|r| r.scope == ReadScope::History).map(|r| r.family))
        .collect();
    graph
        .families
        .iter()
        .enumerate()
        .flat_map(|(f, fam)| {
            let family = FamilyId(f as u32);
            let history = history.contains(&family);
            let views = if fam.global { 1 } else { graph.topology.views() };
            (0..views).map(move |v| ResourceInfo {
                name: fam.name.clone(),
                family,
                view: ViewId(v),
                desc: fam.desc,
                exported: fam.exported.as_ref().map(|(versions, _)| versions[v as usize]),
                history,
                versions: last_version(writers, family, ViewId(v)),
                reset: fam.reset.clone(),
                global: fam.global,
            })
        })
        .collect()
}

/// Resource rows covered by an instance band: the band of a banded resource (a view-sized
/// image, a row buffer), every row of anything else.
fn rows_of<P>(graph: &Graph<P>, family: FamilyId, band: Region) -> Region {
    let fam = &graph.families[family.index()];
    if fam.banded(graph.topology.height) { band } else { fam.desc.full() }
}

#[allow(clippy::too_many_arguments)]
fn instantiate<P>(
    graph: &Graph<P>,
    writers: &WriterMap,
    decl: &PassDecl,
    pass: PassId,
    view: ViewId,
    device: DeviceId,
    region: Region,
    rid: &dyn Fn(FamilyId, ViewId) -> ResourceId,
) -> PassInstance {
    let full = |f: FamilyId| graph.families[f.index()].desc.full();
    let mut reads = Vec::new();
    let mut history_reads = Vec::new();
    for (k, r) in decl.reads.iter().enumerate() {
        let targets = read_targets(graph, writers, r.scope, r.family, &r.versions, view);
        for (i, (family, u, version)) in targets.into_iter().enumerate() {
            let rows = match r.scope {
                ReadScope::Own | ReadScope::History => rows_of(graph, family, region),
                ReadScope::OwnHalo(halo) => rows_of(graph, family, region.grown(halo, full(family).y1)),
                ReadScope::OwnWhole | ReadScope::Sources | ReadScope::EveryView => full(family),
            };
            let origin = match r.scope {
                ReadScope::Own | ReadScope::OwnWhole | ReadScope::OwnHalo(_) => Origin::Own,
                ReadScope::Sources | ReadScope::EveryView => Origin::Source(i as u32),
                ReadScope::History => Origin::History,
            };
            let access = Access {
                resource: rid(family, u),
                version,
                region: rows,
                alloc: AllocId::UNASSIGNED,
                origin,
                decl: k as u16,
                in_place: false,
            };
            if r.scope == ReadScope::History { history_reads.push(access) } else { reads.push(access) }
        }
    }
    let writes = decl
        .writes
        .iter()
        .enumerate()
        .map(|(k, w)| Access {
            resource: rid(w.family, view),
            version: w.versions[view.index()],
            region: rows_of(graph, w.family, region),
            alloc: AllocId::UNASSIGNED,
            origin: Origin::Own,
            decl: k as u16,
            in_place: w.in_place,
        })
        .collect();
    PassInstance { pass, name: decl.name.clone(), view, region, device, reads, writes, history_reads }
}

/// Producer → consumer edges by (resource, version) and row overlap. Also checks that history
/// reads stay on the device of the last writer.
fn derive_edges<P>(
    graph: &Graph<P>,
    instances: &[PassInstance],
    resources: &[ResourceInfo],
) -> Result<Vec<Edge>, GraphError> {
    let mut by_version: HashMap<(ResourceId, u32), Vec<usize>> = HashMap::new();
    for (i, inst) in instances.iter().enumerate() {
        for w in &inst.writes {
            by_version.entry((w.resource, w.version)).or_default().push(i);
        }
    }
    let mut edges = Vec::new();
    for (c, inst) in instances.iter().enumerate() {
        for read in &inst.reads {
            let mut covered = 0;
            for &p in by_version.get(&(read.resource, read.version)).into_iter().flatten() {
                let written =
                    instances[p].writes.iter().find(|w| w.resource == read.resource && w.version == read.version);
                if let Some(overlap) = written.and_then(|w| w.region.intersect(read.region)) {
                    covered += overlap.len();
                    edges.push(Edge {
                        producer: InstanceId(p as u32),
                        consumer: InstanceId(c as u32),
                        access: Access { region: overlap, ..*read },
                    });
                }
            }
            let info = &resources[read.resource.index()];
            let imported = graph.families[info.family.index()].imported && read.version == 0;
            if covered < read.region.len() && !imported {
                let decl = &graph.passes[inst.pass.index()];
                return Err(GraphError::ReadOfUnwritten {
                    pass: inst.name.clone(),
                    resource: info.name.clone(),
                    view: info.view,
                    version: read.version,
                    at: decl.at,
                });
            }
        }
        for h in &inst.history_reads {
            for &p in by_version.get(&(h.resource, h.version)).into_iter().flatten() {
                let writer = &instances[p];
                let overlaps =
                    writer.writes.iter().any(|w| w.resource == h.resource && w.region.intersect(h.region).is_some());
                if overlaps && writer.device != inst.device {
                    return Err(GraphError::HistoryAcrossDevices {
                        pass: inst.name.clone(),
                        resource: resources[h.resource.index()].name.clone(),
                        view: inst.view,
                        reader: inst.device.0,
                        writer: writer.device.0,
                    });
                }
            }
        }
    }
    Ok(edges)
}

/// δ-edges: reads of another view's resource, once per (source view, consuming instance). A
/// global resource belongs to no view and a global pass reduces over views rather than
/// reprojecting them, so neither makes a δ-edge.
fn delta_edges<P>(graph: &Graph<P>, instances: &[PassInstance], resources: &[ResourceInfo]) -> Vec<DeltaEdge> {
    let set: BTreeSet<DeltaEdge> = instances
        .iter()
        .enumerate()
        .filter(|(_, inst)| graph.passes[inst.pass.index()].role != Role::Global)
        .flat_map(|(i, inst)| {
            inst.reads.iter().filter_map(move |r| {
                let info = &resources[r.resource.index()];
                let source = info.view;
                (source != inst.view && !info.global).then_some(DeltaEdge {
                    source,
                    target: inst.view,
                    consumer: InstanceId(i as u32),
                })
            })
        })
        .collect();
    set.into_iter().collect()
}

/// Kahn's algorithm; among ready instances the earliest declared goes first.
fn topological_order(instances: &[PassInstance], edges: &[Edge]) -> Result<Vec<InstanceId>, GraphError> {
    let n = instances.len();
    let mut indegree = vec![0usize; n];
    let mut successors: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
    for e in edges {
        if e.producer != e.consumer && successors[e.producer.index()].insert(e.consumer.index()) {
            indegree[e.consumer.index()] += 1;
        }
    }
    let mut ready: BinaryHeap<Reverse<usize>> = (0..n).filter(|&i| indegree[i] == 0).map(Reverse).collect();
    let mut order = Vec::with_capacity(n);
    while let Some(Reverse(i)) = ready.pop() {
        order.push(InstanceId(i as u32));
        for &s in &successors[i] {
            indegree[s] -= 1;
            if indegree[s] == 0 {
                ready.push(Reverse(s));
            }
        }
    }
    let self_loop = edges.iter().find(|e| e.producer == e.consumer);
    if order.len() < n || self_loop.is_some() {
        // Nodes left after Kahn are on a cycle or downstream of one; peel off the downstream
        // ones (no successor left) so the error names only the passes that form the cycle.
        let mut left: BTreeSet<usize> = (0..n).filter(|&i| indegree[i] > 0).collect();
        while let Some(&tail) = left.iter().find(|&&i| !successors[i].iter().any(|s| left.contains(s))) {
            left.remove(&tail);
        }
        let mut passes: Vec<String> = left.into_iter().map(|i| instances[i].name.clone()).collect();
        passes.extend(self_loop.map(|e| instances[e.producer.index()].name.clone()));
        passes.sort();
        passes.dedup();
        return Err(GraphError::Cycle { passes });
    }
    Ok(order)
}

/// Every splittable pass instance of every view in `bands` row bands, band `b` on device
/// `b % devices`; passes that need their whole view stay on device 0. How one view (or a few)
/// is traced over more devices than a light-field plan allows (it needs a view per device).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BandedPlacement {
    pub devices: u32,
    pub bands: u32,
}

impl Placement for BandedPlacement {
    fn devices(&self) -> u32 {
        self.devices.max(1)
    }

    fn place(&self, pass: PassPlacementInfo<'_>, _view: ViewId, height: u32) -> Vec<(DeviceId, Region)> {
        if !pass.splittable {
            return vec![(DeviceId(0), Region::rows(height))];
        }
        let bands = self.bands.clamp(1, height.max(1));
        Region::bands(height, bands)
            .into_iter()
            .enumerate()
            .map(|(b, region)| (DeviceId(b as u32 % self.devices()), region))
            .collect()
    }
}
