//! Graphviz export of a schedule: one cluster per device with its passes in program order (and,
//! as a comment, every op of the program in the order the backend submits it and the memory
//! barriers between them), producer edges
//! in grey, δ-edges (reprojection reads of another view) dashed blue, each cross-device copy as
//! a red node between clusters, and the op order's compile option as the caption. Output is deterministic: the same schedule
//! always gives the same bytes.

use std::collections::BTreeMap;
use std::fmt::Write;

use crate::ids::CopyId;
use crate::schedule::{CopyKind, Op, Schedule};

const DEVICE_COLOURS: [&str; 8] =
    ["#fde0dd", "#e0f3db", "#deebf7", "#fff7bc", "#efedf5", "#fee6ce", "#e5f5f9", "#f0f0f0"];

/// Arrows by (from, to) node: whether any read it stands for is a δ-edge, and whether it
/// leads into or out of a copy node.
type Arrows = BTreeMap<(String, String), (bool, bool)>;

impl Schedule {
    pub fn to_dot(&self) -> String {
        let mut out = String::new();
        let w = &mut out;
        writeln!(w, "digraph schedule {{").unwrap();
        writeln!(w, "  graph [rankdir=TB, fontname=\"Helvetica\", newrank=true];").unwrap();
        writeln!(w, "  node [shape=box, style=\"rounded,filled\", fontname=\"Helvetica\", fontsize=10];").unwrap();
        writeln!(w, "  edge [color=\"#777777\", arrowsize=0.6];").unwrap();
        self.write_device_clusters(w);
        self.write_copy_nodes(w);
        for ((from, to), (delta, cross)) in self.dependency_arrows() {
            let attrs = match (delta, cross) {
                (true, true) => " [style=dashed, color=\"#cc0000\", label=\"δ\"]",
                (true, false) => " [style=dashed, color=\"#1f5fbf\", label=\"δ\"]",
                (false, true) => " [color=\"#cc0000\"]",
                (false, false) => "",
            };
            writeln!(w, "  {from} -> {to}{attrs};").unwrap();
        }
        self.write_gather_arrows(w);
        self.write_op_order_label(w);
        writeln!(w, "}}").unwrap();
        out
    }

    /// The drawing's caption: how each program's ops are ordered (the compile option).
    pub(crate) fn write_op_order_label(&self, w: &mut String) {
        writeln!(w, "  label=\"op order: {}\"; labelloc=b; fontsize=10;", escape(&self.op_order.to_string())).unwrap();
    }

    /// One cluster per device with its pass instances in program order (and, on device 0, the
    /// finished views).
    fn write_device_clusters(&self, w: &mut String) {
        for program in &self.devices {
            let d = program.device;
            writeln!(w, "  subgraph cluster_{d} {{").unwrap();
            writeln!(
                w,
                "    label=\"{d}\"; style=\"rounded,filled\"; fillcolor=\"{}\"; color=\"#999999\";",
                DEVICE_COLOURS[d.index() % 8]
            )
            .unwrap();
            for op in &program.ops {
                if let Op::Pass(id) = op {
                    let inst = self.instance(*id);
                    let height = self.resources.first().map_or(0, |r| r.desc.rows());
                    // A band's halo reads reach this many rows beyond it (from neighbouring bands).
                    let halo = self.passes[inst.pass.index()].reads.iter().map(|r| r.halo).max().unwrap_or(0);
                    let rows = if inst.region.y0 == 0 && inst.region.y1 >= height {
                        String::new()
                    } else if halo > 0 {
                        format!("\\n{} ±{halo}", inst.region)
                    } else {
                        format!("\\n{}", inst.region)
                    };
                    writeln!(w, "    {id} [label=\"{}\\n{}{rows}\", fillcolor=white];", escape(&inst.name), inst.view)
                        .unwrap();
                }
            }
            // Every op of the program, in the order the backend submits them, and the barriers
            // between them.
            let mut barriers = program.barriers.iter().peekable();
            let mut ops: Vec<String> = Vec::with_capacity(program.ops.len() + program.barriers.len());
            for (index, op) in program.ops.iter().enumerate() {
                if barriers.next_if(|&&b| b as usize == index).is_some() {
                    ops.push("barrier".to_string());
                }
                ops.push(op_token(*op));
            }
            writeln!(w, "    // {d} submits: {}", ops.join(", ")).unwrap();
            if d.0 == 0 && self.gather_copies().next().is_some() {
                writeln!(w, "    gathered [label=\"finished views\", shape=doubleoctagon, fillcolor=\"#ffffff\"];")
                    .unwrap();
            }
            writeln!(w, "  }}").unwrap();
        }
    }

    /// Each copy as a node; the copies of a batch of more than one (`Schedule::batches`) in a
    /// dashed cluster of their own, labelled with the one transfer they travel in.
    fn write_copy_nodes(&self, w: &mut String) {
        let batch_of = self.batch_of_copies();
        for (b, batch) in self.batches.iter().enumerate().filter(|(_, b)| b.copies.len() > 1) {
            writeln!(w, "  subgraph cluster_b{b} {{").unwrap();
            writeln!(
                w,
                "    label=\"batch b{b}: {} copies, {} → {}, {} B\"; style=dashed; color=\"#cc0000\"; fontsize=9;",
                batch.copies.len(),
                batch.from,
                batch.to,
                batch.bytes
            )
            .unwrap();
            for &c in &batch.copies {
                self.write_copy_node(w, c, "    ");
            }
            writeln!(w, "  }}").unwrap();
        }
        for c in (0..self.copies.len()).map(|c| CopyId(c as u32)) {
            let batched = batch_of[c.index()].is_some_and(|b| self.batches[b.index()].copies.len() > 1);
            if !batched {
                self.write_copy_node(w, c, "  ");
            }
        }
    }

    fn write_copy_node(&self, w: &mut String, id: CopyId, indent: &str) {
        let copy = self.copy(id);
        let res = self.resource(copy.resource);
        writeln!(
            w,
            "{indent}{id} [label=\"copy {}@v{} of {}\\n{} → {}, {}\\n{} B\", shape=cds, color=\"#cc0000\", fillcolor=\"#ffdddd\"];",
            escape(&res.name),
            copy.version,
            res.view,
            copy.from,
            copy.to,
            copy.region,
            copy.bytes
        )
        .unwrap();
    }

    /// One arrow per pair of nodes however many resources flow between them; an arrow is a
    /// δ-edge when any of its reads is of another view. A dependency across devices goes
    /// through the copy that carries it.
    fn dependency_arrows(&self) -> Arrows {
        let mut arrows = Arrows::new();
        for e in &self.edges {
            let (p, c) = (self.instance(e.producer), self.instance(e.consumer));
            let delta = self.resource(e.access.resource).view != c.view;
            let mut arrow = |from: String, to: String, delta: bool, cross: bool| {
                let entry = arrows.entry((from, to)).or_insert((false, cross));
                entry.0 |= delta;
            };
            if p.device == c.device {
                arrow(e.producer.to_string(), e.consumer.to_string(), delta, false);
                continue;
            }
            let copy = self.copies.iter().position(|k| {
                k.kind == CopyKind::Dependency
                    && k.resource == e.access.resource
                    && k.version == e.access.version
                    && k.from == p.device
                    && k.to == c.device
                    && k.region.contains(e.access.region)
            });
            if let Some(k) = copy {
                let k = CopyId(k as u32).to_string();
                arrow(e.producer.to_string(), k.clone(), false, true);
                arrow(k, e.consumer.to_string(), delta, true);
            }
        }
        arrows
    }

    /// Each gather, in program order: from the pass that wrote it to the finished views.
    fn write_gather_arrows(&self, w: &mut String) {
        for program in &self.devices {
            for op in &program.ops {
                if let Op::CopyOut(k) = op
                    && self.copy(*k).kind == CopyKind::Gather
                {
                    let producer = self.producer_of(*k);
                    if let Some(p) = producer {
                        writeln!(w, "  {p} -> {k} [color=\"#cc0000\"];").unwrap();
                    }
                    writeln!(w, "  {k} -> gathered [color=\"#cc0000\"];").unwrap();
                }
            }
        }
    }

    /// The instance on the copy's source device that wrote the copied rows.
    fn producer_of(&self, copy: CopyId) -> Option<crate::ids::InstanceId> {
        let k = self.copy(copy);
        self.instances
            .iter()
            .position(|i| {
                i.device == k.from
                    && i.writes
                        .iter()
                        .any(|w| w.resource == k.resource && w.version == k.version && w.region.contains(k.region))
            })
            .map(|i| crate::ids::InstanceId(i as u32))
    }
}

/// An op as the per-device `submits` comment lists it: `p3`, `out c2`, `signal c2`, `wait c2`,
/// `in c2`.
fn op_token(op: Op) -> String {
    match op {
        Op::Pass(p) => p.to_string(),
        Op::CopyOut(c) => format!("out {c}"),
        Op::Signal(c) => format!("signal {c}"),
        Op::Wait(c) => format!("wait {c}"),
        Op::CopyIn(c) => format!("in {c}"),
    }
}

pub(crate) fn escape(s: &str) -> String {
    s.replace('\\', "\\\\").replace('"', "\\\"")
}
