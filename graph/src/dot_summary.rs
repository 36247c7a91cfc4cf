//! The summary drawing of a schedule, for schedules too big to draw instance by instance (the
//! full DOT of multiscopic on 8 devices under fine-all is 9 MB and Graphviz does not finish):
//! one node per pass and device with its instance and view counts, one node per kind of copy
//! and device pair with its count and bytes, and one arrow per pair of nodes labelled with the
//! number of dependencies it stands for. A copy node has one arrow in, from the sending device's
//! cluster, and one out, to the receiving device's cluster: per pass, fine-all on 8 devices had
//! over 1,000 arrows, which Graphviz took a minute to lay out; per cluster it takes a fraction of
//! a second. Deterministic like [`Schedule::to_dot`].

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt::Write;

use crate::ids::DeviceId;
use crate::schedule::{CopyKind, Op, Schedule};

/// A group of pass instances: one pass on one device.
type Group = (DeviceId, String);

#[derive(Default)]
struct Arrow {
    count: u64,
    delta: bool,
}

impl Arrow {
    fn add(&mut self, delta: bool) {
        self.count += 1;
        self.delta |= delta;
    }

    /// Graphviz attributes of a δ arrow (none for a plain one).
    fn style(&self) -> &'static str {
        if self.delta { ", style=dashed, color=\"#1f5fbf\"" } else { "" }
    }

    fn label(&self) -> String {
        format!("{}{}", self.count, if self.delta { " δ" } else { "" })
    }
}

/// The pass groups, numbered in program order of their first instance per device.
struct Groups {
    order: Vec<Group>,
    views: BTreeMap<Group, BTreeSet<u32>>,
    instances: BTreeMap<Group, u64>,
    node_of: HashMap<Group, usize>,
}

impl Groups {
    fn of(schedule: &Schedule) -> Self {
        let mut order: Vec<Group> = Vec::new();
        let mut views: BTreeMap<Group, BTreeSet<u32>> = BTreeMap::new();
        let mut instances: BTreeMap<Group, u64> = BTreeMap::new();
        for program in &schedule.devices {
            for op in &program.ops {
                if let Op::Pass(id) = op {
                    let inst = schedule.instance(*id);
                    let group = (inst.device, inst.name.clone());
                    if !instances.contains_key(&group) {
                        order.push(group.clone());
                    }
                    *instances.entry(group.clone()).or_default() += 1;
                    views.entry(group).or_default().insert(inst.view.0);
                }
            }
        }
        let node_of = order.iter().enumerate().map(|(i, g)| (g.clone(), i)).collect();
        Self { order, views, instances, node_of }
    }

    /// The node number of `name`'s group on `device`.
    fn node(&self, device: DeviceId, name: &str) -> usize {
        self.node_of[&(device, name.to_string())]
    }
}

/// Copies by (is a gather, from, to): their count and bytes.
/// Copies by (gather, from, to): how many, their bytes and the batches they travel in.
type CopyTotals = BTreeMap<(bool, DeviceId, DeviceId), (u64, u64, u64)>;

fn copy_node(gather: bool, from: DeviceId, to: DeviceId) -> String {
    let kind = if gather { "gather" } else { "copy" };
    format!("{kind}_{}_{}", from.0, to.0)
}

/// The drawing's arrows.
#[derive(Default)]
struct Arrows {
    /// Between two nodes (passes of one device, a gather and its ends), by node names.
    direct: BTreeMap<(String, String), Arrow>,
    /// Dependencies through a copy node, per device pair: their count, whether any is a δ-edge,
    /// and the nodes the two cluster arrows attach to (the sender's last producing pass, the
    /// receiver's first consuming pass; node numbers follow program order within a device).
    crossing: BTreeMap<(DeviceId, DeviceId), (Arrow, usize, usize)>,
}

impl Arrows {
    fn add(&mut self, from: String, to: String, delta: bool) {
        self.direct.entry((from, to)).or_default().add(delta);
    }
}

impl Schedule {
    /// The schedule with one node per pass and device (see the module documentation).
    pub fn to_dot_summary(&self) -> String {
        let groups = Groups::of(self);
        let copies = self.copy_totals();
        let mut arrows = self.group_arrows(&groups);
        self.add_gather_group_arrows(&groups, &mut arrows);
        let mut out = String::new();
        let w = &mut out;
        writeln!(w, "digraph schedule_summary {{").unwrap();
        writeln!(w, "  graph [rankdir=TB, fontname=\"Helvetica\", newrank=true, compound=true];").unwrap();
        writeln!(w, "  node [shape=box, style=\"rounded,filled\", fontname=\"Helvetica\", fontsize=10];").unwrap();
        writeln!(w, "  edge [color=\"#777777\", arrowsize=0.6, fontname=\"Helvetica\", fontsize=9];").unwrap();
        self.write_group_clusters(w, &groups, &copies);
        write_copy_nodes(w, &copies);
        write_arrows(w, &arrows);
        self.write_op_order_label(w);
        writeln!(w, "}}").unwrap();
        out
    }

    fn copy_totals(&self) -> CopyTotals {
        let mut copies = CopyTotals::new();
        for c in &self.copies {
            let entry = copies.entry((c.kind == CopyKind::Gather, c.from, c.to)).or_default();
            entry.0 += 1;
            entry.1 += c.bytes;
        }
        for b in &self.batches {
            copies.entry((false, b.from, b.to)).or_default().2 += 1;
        }
        copies
    }

    /// One arrow per pair of pass groups on one device, one crossing per device pair.
    fn group_arrows(&self, groups: &Groups) -> Arrows {
        let mut arrows = Arrows::default();
        for e in &self.edges {
            let (p, c) = (self.instance(e.producer), self.instance(e.consumer));
            let (pn, cn) = (groups.node(p.device, &p.name), groups.node(c.device, &c.name));
            let delta = self.resource(e.access.resource).view != c.view;
            if p.device == c.device {
                arrows.add(format!("p{pn}"), format!("p{cn}"), delta);
            } else {
                let (a, last_producer, first_consumer) =
                    arrows.crossing.entry((p.device, c.device)).or_insert((Arrow::default(), pn, cn));
                a.add(delta);
                *last_producer = (*last_producer).max(pn);
                *first_consumer = (*first_consumer).min(cn);
            }
        }
        arrows
    }

    /// Gathers start at the pass that wrote the gathered version on the sending device and end
    /// at the finished views.
    fn add_gather_group_arrows(&self, groups: &Groups, arrows: &mut Arrows) {
        let mut writer: HashMap<(u32, u32, DeviceId), usize> = HashMap::new();
        for inst in &self.instances {
            for w in &inst.writes {
                writer.entry((w.resource.0, w.version, inst.device)).or_insert(groups.node(inst.device, &inst.name));
            }
        }
        for c in self.copies.iter().filter(|c| c.kind == CopyKind::Gather) {
            let k = copy_node(true, c.from, c.to);
            if let Some(p) = writer.get(&(c.resource.0, c.version, c.from)) {
                arrows.add(format!("p{p}"), k.clone(), false);
            }
            arrows.add(k, "gathered".into(), false);
        }
    }

    /// One cluster per device with its pass groups (and, on device 0, the finished views).
    fn write_group_clusters(&self, w: &mut String, groups: &Groups, copies: &CopyTotals) {
        for program in &self.devices {
            let d = program.device;
            writeln!(w, "  subgraph cluster_{d} {{").unwrap();
            writeln!(w, "    label=\"{d}\"; style=\"rounded,filled\"; fillcolor=\"#f4f4f4\"; color=\"#999999\";")
                .unwrap();
            for (i, group) in groups.order.iter().enumerate().filter(|(_, g)| g.0 == d) {
                writeln!(
                    w,
                    "    p{i} [label=\"{}\\n{} instances, {} views\", fillcolor=white];",
                    group.1.replace('\\', "\\\\").replace('"', "\\\""),
                    groups.instances[group],
                    groups.views[group].len()
                )
                .unwrap();
            }
            if d.0 == 0 && copies.keys().any(|k| k.0) {
                writeln!(w, "    gathered [label=\"finished views\", shape=doubleoctagon, fillcolor=\"#ffffff\"];")
                    .unwrap();
            }
            writeln!(w, "  }}").unwrap();
        }
    }
}

fn write_copy_nodes(w: &mut String, copies: &CopyTotals) {
    for ((gather, from, to), (count, bytes, batches)) in copies {
        let what = if *gather { "gather" } else { "copies" };
        let batched = if *batches > 0 { format!("\\nin {batches} batches") } else { String::new() };
        writeln!(
            w,
            "  {} [label=\"{count} {what}\\n{from} → {to}\\n{bytes} B{batched}\", shape=cds, color=\"#cc0000\", fillcolor=\"#ffdddd\"];",
            copy_node(*gather, *from, *to)
        )
        .unwrap();
    }
}

fn write_arrows(w: &mut String, arrows: &Arrows) {
    for ((from, to), a) in &arrows.direct {
        writeln!(w, "  {from} -> {to} [label=\"{}\"{}];", a.label(), a.style()).unwrap();
    }
    for ((from, to), (a, last_producer, first_consumer)) in &arrows.crossing {
        let k = copy_node(false, *from, *to);
        let label = a.label();
        writeln!(w, "  p{last_producer} -> {k} [ltail=cluster_{from}, label=\"{label}\"];").unwrap();
        writeln!(w, "  {k} -> p{first_consumer} [lhead=cluster_{to}, label=\"{label}\"{}];", a.style()).unwrap();
    }
}
