//! Copy batches (`Schedule::batches`): one transfer per device pair and stage under the fine
//! schemes, none under multi-source; each corruption reported with its exact variant.

mod common;

use common::*;
use parallax_graph::*;

fn schedule(scheme: Scheme, devices: u32) -> Schedule {
    test_schedule(&grid(4, 3, 8), devices, scheme, AssignStrategy::RoundRobin, None).1
}

/// A batch of more than one copy, and its index.
fn big_batch(s: &Schedule) -> usize {
    s.batches.iter().position(|b| b.copies.len() > 1).expect("a batch of several copies")
}

#[test]
fn fine_schemes_move_each_pairs_copies_of_a_stage_in_one_batch() {
    for scheme in [Scheme::FineAll, Scheme::FineSources] {
        let s = schedule(scheme, 3);
        assert!(s.validate().is_ok(), "{}", s.validate());
        let copies = s.dependency_copies().count();
        assert!(copies > 0);
        assert_eq!(s.batches.iter().map(|b| b.copies.len()).sum::<usize>(), copies);
        assert!(s.batches.len() < copies, "{scheme:?}: {} batches for {copies} copies", s.batches.len());
        for b in &s.batches {
            assert!(b.copies.iter().all(|&c| (s.copy(c).from, s.copy(c).to) == (b.from, b.to)));
            assert_eq!(b.bytes, b.copies.iter().map(|&c| s.copy(c).bytes).sum::<u64>());
        }
    }
}

#[test]
fn fine_all_has_at_most_one_batch_per_pair_and_stage() {
    let s = schedule(Scheme::FineAll, 3);
    // A stage: the pass whose instances produce the batch's copies.
    let mut seen = std::collections::HashSet::new();
    for b in &s.batches {
        let producer = |c: CopyId| {
            let k = s.copy(c);
            s.instances
                .iter()
                .find(|i| {
                    i.device == k.from && i.writes.iter().any(|w| w.resource == k.resource && w.version == k.version)
                })
                .map(|i| i.pass)
                .unwrap()
        };
        let passes: std::collections::BTreeSet<PassId> = b.copies.iter().map(|&c| producer(c)).collect();
        for pass in passes {
            assert!(seen.insert((b.from, b.to, pass)), "pass {pass} sends {} → {} in two batches", b.from, b.to);
        }
    }
}

#[test]
fn multi_source_has_no_batches() {
    let s = schedule(Scheme::MultiSource, 3);
    assert!(s.gather_copies().count() > 0);
    assert!(s.batches.is_empty());
}

#[test]
fn a_copy_left_out_of_its_batch_is_reported() {
    let mut s = schedule(Scheme::FineAll, 3);
    let b = big_batch(&s);
    let c = s.batches[b].copies.pop().unwrap();
    s.batches[b].bytes -= s.copy(c).bytes;
    assert_eq!(s.validate().errors, vec![ScheduleError::CopyBatchCount { copy: c, batches: 0 }]);
}

#[test]
fn a_copy_in_two_batches_is_reported() {
    let mut s = schedule(Scheme::FineAll, 3);
    let b = big_batch(&s);
    let c = s.batches[b].copies[0];
    let bytes = s.copy(c).bytes;
    let mut twin = s.batches[b].clone();
    twin.copies = vec![c];
    twin.bytes = bytes;
    s.batches.push(twin);
    assert_eq!(s.validate().errors, vec![ScheduleError::CopyBatchCount { copy: c, batches: 2 }]);
}

#[test]
fn a_batch_of_another_pair_is_reported() {
    let mut s = schedule(Scheme::FineAll, 3);
    let b = big_batch(&s);
    let (from, to) = (s.batches[b].from, s.batches[b].to);
    let other = s.batches.iter().position(|x| (x.from, x.to) != (from, to)).unwrap();
    let c = s.batches[other].copies.pop().unwrap();
    let bytes = s.copy(c).bytes;
    s.batches[other].bytes -= bytes;
    s.batches[b].copies.push(c);
    s.batches[b].bytes += bytes;
    let errors = s.validate().errors;
    assert!(errors.contains(&ScheduleError::BatchForeignCopy { batch: BatchId(b as u32), copy: c }), "{errors:?}");
}

#[test]
fn a_wrong_batch_byte_count_is_reported() {
    let mut s = schedule(Scheme::FineAll, 3);
    let b = big_batch(&s);
    let expected = s.batches[b].bytes;
    s.batches[b].bytes += 4;
    assert_eq!(
        s.validate().errors,
        vec![ScheduleError::BatchBytesMismatch { batch: BatchId(b as u32), expected, actual: expected + 4 }]
    );
}

#[test]
fn a_batch_split_by_a_pass_is_reported() {
    let mut s = schedule(Scheme::FineAll, 3);
    let b = big_batch(&s);
    let (from, last) = (s.batches[b].from, *s.batches[b].copies.last().unwrap());
    let program = &mut s.devices[from.index()];
    let at = program.ops.iter().position(|&o| o == Op::CopyOut(last)).unwrap();
    // A pass that has run already, listed again just before the batch's last copy-out.
    let pass = program.ops[..at].iter().rev().find(|o| matches!(o, Op::Pass(_))).copied().unwrap();
    insert_op(program, at, pass);
    let errors = s.validate().errors;
    assert!(errors.contains(&ScheduleError::BatchSplit { batch: BatchId(b as u32), device: from }), "{errors:?}");
}

#[test]
fn overlapping_regions_in_one_batch_are_reported() {
    let mut s = schedule(Scheme::FineAll, 3);
    let b = big_batch(&s);
    let (first, second) = (s.batches[b].copies[0], s.batches[b].copies[1]);
    // The second copy lands on the first one's rows of the first one's allocation.
    let (alloc, region) = (s.copy(first).dst_alloc, s.copy(first).region);
    s.copies[second.index()].dst_alloc = alloc;
    s.copies[second.index()].region = region;
    let errors = s.validate().errors;
    assert!(
        errors.contains(&ScheduleError::BatchRegionsOverlap { batch: BatchId(b as u32), first, second }),
        "{errors:?}"
    );
}

/// A filter reading one row around its band: under fine-all its copies are halo rows.
fn halo_schedule() -> Schedule {
    let plan = Partition::new(
        &grid(3, 1, 12),
        &PartitionConfig { devices: 3, scheme: Scheme::FineAll, assign: AssignStrategy::RoundRobin, sources: None },
    )
    .unwrap();
    let mut graph = Graph::new(plan.topology.clone());
    let mut x = graph.image("x", Format::Rgba32f);
    let mut y = graph.image("y", Format::Rgba32f);
    graph.pass("produce", Role::All).write(&mut x).add();
    graph.pass("filter", Role::All).read_halo(&x, 1).write(&mut y).add();
    graph.export(&y);
    compile(&graph, &plan).unwrap().into_schedule()
}

#[test]
fn halo_copies_carry_the_rows_read_and_no_more() {
    let mut s = halo_schedule();
    assert!(s.validate().is_ok(), "{}", s.validate());
    let x: Vec<&CrossCopy> = s.dependency_copies().filter(|k| s.resource(k.resource).name == "x").collect();
    // 12 rows in bands of 4: each band sends its edge row to each neighbour.
    assert!(!x.is_empty() && x.iter().all(|k| k.region.len() == 1), "{x:?}");
    // Grown to the producer's whole band, a copy carries rows nobody reads.
    let c = CopyId(s.copies.iter().position(|k| k.kind == CopyKind::Dependency && k.region.len() == 1).unwrap() as u32);
    let read = s.copy(c).region;
    let band = Region::new(read.y0 / 4 * 4, read.y0 / 4 * 4 + 4);
    s.copies[c.index()].region = band;
    s.copies[c.index()].bytes = s.resource(s.copy(c).resource).desc.bytes(band);
    let b = s.batch_of_copies()[c.index()].unwrap();
    s.batches[b.index()].bytes = s.batches[b.index()].copies.iter().map(|&k| s.copy(k).bytes).sum();
    assert_eq!(s.validate().errors, vec![ScheduleError::CopyRowsUnread { copy: c, read, copied: band }]);
}
