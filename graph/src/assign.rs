//! Assigning views to N sets (one per device): the paper's round-robin and contiguous
//! strategies (§4.6), and `compact`, our own: balanced and spatially compact.
//!
//! `compact` is a recursive bisection. A group of devices is split in two halves; the views are
//! sorted along one axis and cut so each half gets exactly the views its devices are owed
//! (⌊M/N⌋ or ⌈M/N⌉ each). Both axes and both ways round are tried, and the cut with the smaller
//! spread (sum of distances to each half's centroid) wins, so wide gaps such as the one between
//! the NELF eye blocks are cut first.

use glam::DVec2;

use crate::error::PartitionError;
use crate::ids::ViewId;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AssignStrategy {
    RoundRobin,
    Contiguous,
    Compact,
}

impl AssignStrategy {
    pub fn name(self) -> &'static str {
        match self {
            AssignStrategy::RoundRobin => "round-robin",
            AssignStrategy::Contiguous => "contiguous",
            AssignStrategy::Compact => "compact",
        }
    }
}

impl std::str::FromStr for AssignStrategy {
    type Err = PartitionError;
    fn from_str(s: &str) -> Result<Self, PartitionError> {
        match s {
            "round-robin" => Ok(AssignStrategy::RoundRobin),
            "contiguous" => Ok(AssignStrategy::Contiguous),
            "compact" => Ok(AssignStrategy::Compact),
            _ => Err(PartitionError::UnknownAssignment(s.to_string())),
        }
    }
}

/// Views split into sets; set i runs on device i under the multi-source scheme.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Assignment {
    pub set_of_view: Vec<u32>,
    /// Members of each set in increasing view order.
    pub sets: Vec<Vec<ViewId>>,
}

impl Assignment {
    fn from_set_of_view(set_of_view: Vec<u32>, n: u32) -> Self {
        let mut sets = vec![Vec::new(); n as usize];
        for (v, &s) in set_of_view.iter().enumerate() {
            sets[s as usize].push(ViewId(v as u32));
        }
        Assignment { set_of_view, sets }
    }
}

/// Target size of set i: the first M mod N sets get one extra view.
fn quota(m: usize, n: usize, i: usize) -> usize {
    m / n + usize::from(i < m % n)
}

/// Splits the views at `positions` into `n` sets. Requires 1 ≤ n ≤ M.
pub fn assign(strategy: AssignStrategy, positions: &[DVec2], n: u32) -> Result<Assignment, PartitionError> {
    let m = positions.len();
    if n == 0 {
        return Err(PartitionError::NoDevices);
    }
    if n as usize > m {
        return Err(PartitionError::MoreDevicesThanViews { devices: n, views: m as u32 });
    }
    let set_of_view = match strategy {
        AssignStrategy::RoundRobin => (0..m).map(|v| (v % n as usize) as u32).collect(),
        AssignStrategy::Contiguous => {
            let mut out = Vec::with_capacity(m);
            for s in 0..n as usize {
                out.extend(std::iter::repeat_n(s as u32, quota(m, n as usize, s)));
            }
            out
        }
        AssignStrategy::Compact => {
            let mut out = vec![0; m];
            let views: Vec<usize> = (0..m).collect();
            let quotas: Vec<usize> = (0..n as usize).map(|i| quota(m, n as usize, i)).collect();
            bisect(positions, views, &quotas, 0, &mut out);
            out
        }
    };
    Ok(Assignment::from_set_of_view(set_of_view, n))
}

/// Assigns `views` to the sets `first_set..first_set + quotas.len()`.
fn bisect(positions: &[DVec2], views: Vec<usize>, quotas: &[usize], first_set: usize, out: &mut [u32]) {
    if quotas.len() == 1 {
        for v in views {
            out[v] = first_set as u32;
        }
        return;
    }
    let half = quotas.len() / 2;
    let mut best: Option<(f64, Vec<usize>, Vec<usize>, bool)> = None;
    // Try cutting along x and y, and giving the low side either group of devices.
    for axis in [0usize, 1] {
        let mut sorted = views.clone();
        sorted.sort_by(|&a, &b| {
            let (pa, pb) = (positions[a], positions[b]);
            pa[axis].total_cmp(&pb[axis]).then(pa[1 - axis].total_cmp(&pb[1 - axis])).then(a.cmp(&b))
        });
        for low_first in [true, false] {
            let low_quotas = if low_first { &quotas[..half] } else { &quotas[half..] };
            let cut: usize = low_quotas.iter().sum();
            let (lo, hi) = sorted.split_at(cut);
            let cost = spread(positions, lo) + spread(positions, hi);
            if best.as_ref().is_none_or(|b| cost < b.0) {
                best = Some((cost, lo.to_vec(), hi.to_vec(), low_first));
            }
        }
    }
    let (_, lo, hi, low_first) = best.expect("two axes were tried");
    let (first_views, second_views) = if low_first { (lo, hi) } else { (hi, lo) };
    bisect(positions, first_views, &quotas[..half], first_set, out);
    bisect(positions, second_views, &quotas[half..], first_set + half, out);
}

/// Sum of distances from each view to the group's centroid.
fn spread(positions: &[DVec2], views: &[usize]) -> f64 {
    if views.is_empty() {
        return 0.0;
    }
    let c = views.iter().map(|&v| positions[v]).sum::<DVec2>() / views.len() as f64;
    views.iter().map(|&v| (positions[v] - c).length()).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(m: usize) -> Vec<DVec2> {
        (0..m).map(|i| DVec2::new(i as f64, 0.0)).collect()
    }

    #[test]
    fn paper_strategies() {
        let a = assign(AssignStrategy::RoundRobin, &line(7), 3).unwrap();
        assert_eq!(a.set_of_view, vec![0, 1, 2, 0, 1, 2, 0]);
        let a = assign(AssignStrategy::Contiguous, &line(7), 3).unwrap();
        assert_eq!(a.set_of_view, vec![0, 0, 0, 1, 1, 2, 2]);
    }

    #[test]
    fn every_strategy_is_balanced() {
        for strategy in [AssignStrategy::RoundRobin, AssignStrategy::Contiguous, AssignStrategy::Compact] {
            for (m, n) in [(7, 3), (100, 4), (72, 3), (5, 5), (1, 1)] {
                let a = assign(strategy, &line(m), n).unwrap();
                for s in &a.sets {
                    assert!(
                        s.len() == m / n as usize || s.len() == m.div_ceil(n as usize),
                        "{strategy:?} {m} {n}: {:?}",
                        a.sets
                    );
                }
            }
        }
    }

    #[test]
    fn bad_device_counts() {
        assert_eq!(assign(AssignStrategy::Compact, &line(3), 0), Err(PartitionError::NoDevices));
        assert_eq!(
            assign(AssignStrategy::Compact, &line(3), 4),
            Err(PartitionError::MoreDevicesThanViews { devices: 4, views: 3 })
        );
    }
}
