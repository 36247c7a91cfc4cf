//! Halo reads (`PassBuilder::read_halo`): a band reads its own rows and a stated number of rows
//! around them, so a banded scheme copies those rows of the neighbouring bands instead of whole
//! views; `Schedule::halo_reads` (plan's `halo_rows`, `halo_bytes`) counts them and the DOT
//! shows each band's reach.

mod common;

use common::*;
use parallax_graph::*;

/// `views`×1 views of 16×16, each in `devices` row bands, band `b` on device `b`: `shade`
/// writes `color`, `blur` reads it with `halo` rows around each band (whole views when `None`).
fn blur(views: u32, devices: u32, halo: Option<u32>) -> Schedule {
    let config =
        PartitionConfig { devices: 1, scheme: Scheme::FineAll, assign: AssignStrategy::Compact, sources: None };
    let plan = Partition::new(&grid(views, 1, 16), &config).unwrap();
    let mut g = Graph::new(plan.topology.clone());
    let mut color = g.image("color", Format::Rgba32f);
    let mut out = g.image("out", Format::Rgba32f);
    g.pass("shade", Role::All).write(&mut color).add();
    let pass = g.pass("blur", Role::All);
    let pass = match halo {
        Some(rows) => pass.read_halo(&color, rows),
        None => pass.read_whole(&color),
    };
    pass.write(&mut out).add();
    g.export(&out);
    let schedule = compile(&g, &BandedPlacement { devices, bands: devices }).unwrap();
    assert_eq!(schedule.validate().errors, vec![], "{devices} devices, halo {halo:?}");
    schedule.into_schedule()
}

/// Rows `[y0, y1)` of every copy of `color` from device `from` to device `to`.
fn copied_rows(s: &Schedule, from: u32, to: u32) -> Vec<(u32, u32)> {
    s.dependency_copies()
        .filter(|c| s.resource(c.resource).name == "color" && c.from == DeviceId(from) && c.to == DeviceId(to))
        .map(|c| (c.region.y0, c.region.y1))
        .collect()
}

#[test]
fn two_bands_copy_only_the_rows_within_reach_of_each_other() {
    // Bands [0, 8) on device 0 and [8, 16) on device 1; each reads 3 rows of the other.
    let s = blur(1, 2, Some(3));
    let reads: Vec<(u32, u32)> =
        s.instances.iter().filter(|i| i.name == "blur").map(|i| (i.reads[0].region.y0, i.reads[0].region.y1)).collect();
    assert_eq!(reads, vec![(0, 11), (5, 16)]);
    assert_eq!(copied_rows(&s, 0, 1), vec![(5, 8)]);
    assert_eq!(copied_rows(&s, 1, 0), vec![(8, 11)]);
    // Read whole, each device receives the other's whole band.
    let whole = blur(1, 2, None);
    assert_eq!(copied_rows(&whole, 0, 1), vec![(0, 8)]);
    assert_eq!(copied_rows(&whole, 1, 0), vec![(8, 16)]);
}

#[test]
fn halo_rows_and_bytes_count_the_reach_beyond_each_band_clamped_to_the_view() {
    // 3 views, 2 bands each: 3 rows beyond each band, 16 texels of 16 bytes a row.
    let s = blur(3, 2, Some(3));
    assert_eq!(s.halo_reads(), HaloReads { rows: 3 * 2 * 3, bytes: 3 * 2 * 3 * 16 * 16 });
    // Bands [0, 5), [5, 10), [10, 16) reaching 10 rows: 10, 5 + 6 and 10 rows beyond them.
    let s = blur(1, 3, Some(10));
    assert_eq!(s.halo_reads().rows, 10 + 11 + 10);
    // One device: one band, the whole view; nothing beyond it.
    assert_eq!(blur(1, 1, Some(3)).halo_reads(), HaloReads::default());
    assert_eq!(blur(1, 2, None).halo_reads(), HaloReads::default(), "a whole read is no halo read");
}

#[test]
fn a_halo_of_zero_rows_is_a_read_of_the_own_rows() {
    let s = blur(1, 2, Some(0));
    assert!(s.instances.iter().filter(|i| i.name == "blur").all(|i| i.reads[0].region == i.region));
    assert_eq!(copied_rows(&s, 0, 1), vec![]);
}

#[test]
fn the_dot_shows_each_bands_reach() {
    let dot = blur(1, 2, Some(3)).to_dot();
    assert!(dot.contains("rows 0..8 ±3\""), "{dot}");
    assert!(dot.contains("rows 8..16 ±3\""), "{dot}");
    assert!(!blur(1, 2, None).to_dot().contains('±'));
}
