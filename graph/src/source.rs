//! Source selection: the geometric median of a set of views (Weiszfeld's algorithm made robust),
//! the view nearest to it (the paper's medoid approximation, §3.1), and the manual source
//! placement of the baselines (§4.1.3).
//!
//! Plain Weiszfeld divides by the distance to every point and so breaks down when an iterate
//! lands exactly on a view. We use the Vardi–Zhang modification: coincident points are handled
//! as a weight η at the iterate; if the pull of the other points is no stronger than η the
//! iterate is the median, otherwise it steps off the point. Duplicated positions are merged into
//! weighted points first, so the case "iterate on a point" covers them too. Weiszfeld also
//! crawls when the median lies very close to (not on) a view; each iteration therefore also
//! tries a Newton step and keeps whichever step lowers the objective more.

use glam::DVec2;

use crate::ids::ViewId;

/// Iteration cap: Weiszfeld converges linearly; 10⁴ steps is far beyond what grids need and
/// keeps degenerate inputs bounded.
pub const MAX_ITERATIONS: usize = 10_000;

/// Result of the median search, with the iterations spent (for tests and reports).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Median {
    pub point: DVec2,
    pub iterations: usize,
}

/// Geometric median of `points` (minimises the sum of Euclidean distances). `None` when empty
/// or when a coordinate is not finite.
pub fn geometric_median(points: &[DVec2]) -> Option<Median> {
    if points.is_empty() || points.iter().any(|p| !p.is_finite()) {
        return None;
    }
    let weighted = merge_duplicates(points);
    if weighted.len() == 1 {
        return Some(Median { point: weighted[0].0, iterations: 0 });
    }
    let scale = weighted.iter().map(|(p, _)| (*p - weighted[0].0).length()).fold(0.0, f64::max);
    let tolerance = scale * 1e-12;
    // Weiszfeld crawls toward a median that sits on a data point; test those exactly first
    // (a point is optimal iff the unit pull of all others is no stronger than its weight).
    if let Some(&(p, _)) = weighted.iter().find(|&&(p, w)| pull_at(&weighted, p, tolerance).length() <= w) {
        return Some(Median { point: p, iterations: 0 });
    }
    let total: f64 = weighted.iter().map(|(_, w)| w).sum();
    // Start from the weighted centroid: inside the convex hull, usually close to the median.
    let mut y = weighted.iter().map(|(p, w)| *p * *w).sum::<DVec2>() / total;
    let mut cost = weighted_cost(&weighted, y);
    for iteration in 1..=MAX_ITERATIONS {
        // Weiszfeld crawls when the median lies close to (not on) a view; a Newton step on the
        // smooth objective converges there in a few steps. Take whichever lowers the cost more,
        // so every step is a descent step and Weiszfeld's convergence guarantee still holds.
        let plain = weiszfeld_step(&weighted, y, tolerance);
        let mut next = plain;
        let mut next_cost = weighted_cost(&weighted, plain);
        if let Some(newton) = newton_step(&weighted, y, tolerance) {
            let newton_cost = weighted_cost(&weighted, newton);
            if newton_cost < next_cost {
                (next, next_cost) = (newton, newton_cost);
            }
        }
        if next_cost > cost {
            next = y; // neither step improves: converged to rounding
        }
        cost = cost.min(next_cost);
        let moved = (next - y).length();
        y = next;
        if moved <= tolerance {
            return Some(Median { point: y, iterations: iteration });
        }
    }
    Some(Median { point: y, iterations: MAX_ITERATIONS })
}

fn weighted_cost(points: &[(DVec2, f64)], y: DVec2) -> f64 {
    points.iter().map(|(p, w)| (*p - y).length() * w).sum()
}

/// Merges identical positions into (position, multiplicity).
fn merge_duplicates(points: &[DVec2]) -> Vec<(DVec2, f64)> {
    let mut out: Vec<(DVec2, f64)> = Vec::new();
    for p in points {
        match out.iter_mut().find(|(q, _)| q == p) {
            Some((_, w)) => *w += 1.0,
            None => out.push((*p, 1.0)),
        }
    }
    out
}

/// Σ w (x − y)/|x − y| over the points not at `y`.
fn pull_at(points: &[(DVec2, f64)], y: DVec2, tolerance: f64) -> DVec2 {
    points
        .iter()
        .filter_map(|&(p, w)| {
            let d = (p - y).length();
            (d > tolerance).then(|| (p - y) * (w / d))
        })
        .sum()
}

/// Newton step on Σ w|p − y| from `y`; None at a data point or with a singular Hessian
/// (all points collinear through `y`).
fn newton_step(points: &[(DVec2, f64)], y: DVec2, tolerance: f64) -> Option<DVec2> {
    let (mut g, mut hxx, mut hxy, mut hyy) = (DVec2::ZERO, 0.0, 0.0, 0.0);
    for &(p, w) in points {
        let v = y - p;
        let d = v.length();
        if d <= tolerance {
            return None;
        }
        let u = v / d;
        g += u * w;
        let k = w / d;
        hxx += k * (1.0 - u.x * u.x);
        hxy -= k * u.x * u.y;
        hyy += k * (1.0 - u.y * u.y);
    }
    let det = hxx * hyy - hxy * hxy;
    if det.abs() <= f64::EPSILON * (hxx * hyy).abs().max(f64::MIN_POSITIVE) {
        return None;
    }
    let step = DVec2::new(hyy * g.x - hxy * g.y, hxx * g.y - hxy * g.x) / det;
    Some(y - step)
}

/// One Vardi–Zhang step from `y`.
fn weiszfeld_step(points: &[(DVec2, f64)], y: DVec2, tolerance: f64) -> DVec2 {
    let mut eta = 0.0; // weight of the point the iterate sits on, if any
    let mut weighted_sum = DVec2::ZERO;
    let mut inverse_sum = 0.0;
    let mut pull = DVec2::ZERO; // R(y): the unit pull of all other points
    for &(p, w) in points {
        let d = (p - y).length();
        if d <= tolerance {
            eta += w;
            continue;
        }
        weighted_sum += p * (w / d);
        inverse_sum += w / d;
        pull += (p - y) * (w / d);
    }
    if inverse_sum == 0.0 {
        return y;
    }
    let t = weighted_sum / inverse_sum;
    if eta == 0.0 {
        return t;
    }
    let r = pull.length();
    if r <= eta {
        return y; // the point the iterate sits on is optimal
    }
    let step = eta / r;
    t * (1.0 - step) + y * step.min(1.0)
}

/// The view nearest to the geometric median of `members` (ties → lowest view index, with a
/// tolerance so that rounding in the median does not break symmetric ties arbitrarily).
pub fn medoid(members: &[ViewId], position: impl Fn(ViewId) -> DVec2) -> Option<ViewId> {
    let points: Vec<DVec2> = members.iter().map(|&v| position(v)).collect();
    let median = geometric_median(&points)?.point;
    nearest(members, &points, median)
}

fn nearest(members: &[ViewId], points: &[DVec2], target: DVec2) -> Option<ViewId> {
    let scale = points.iter().map(|p| (*p - points[0]).length()).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    let tie = scale * 1e-9;
    let mut best: Option<(f64, ViewId)> = None;
    for (&v, p) in members.iter().zip(points) {
        let d = (*p - target).length();
        best = match best {
            Some((bd, bv)) if d > bd + tie || (d > bd - tie && v > bv) => Some((bd, bv)),
            _ => Some((d, v)),
        };
    }
    best.map(|(_, v)| v)
}

/// Sum of distances from `p` to `points`: the Weber objective.
pub fn weber_cost(points: &[DVec2], p: DVec2) -> f64 {
    points.iter().map(|q| (*q - p).length()).sum()
}

/// The baselines' manual sources (paper §4.1.3): k odd → the k views nearest the centre of the
/// light field; k even → corners, picked farthest-first from the centre, each next one as far as
/// possible from those already picked (so k = 2 gives opposite corners). Ties → lowest index.
pub fn baseline_sources(positions: &[DVec2], centre: DVec2, k: usize) -> Vec<ViewId> {
    let k = k.min(positions.len());
    let scale = positions.iter().map(|p| (*p - centre).length()).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    let tie = scale * 1e-9;
    let views = (0..positions.len() as u32).map(ViewId);
    if k % 2 == 1 {
        let mut ranked: Vec<ViewId> = views.collect();
        ranked.sort_by(|a, b| {
            let (da, db) = ((positions[a.index()] - centre).length(), (positions[b.index()] - centre).length());
            if (da - db).abs() <= tie { a.cmp(b) } else { da.total_cmp(&db) }
        });
        ranked.truncate(k);
        ranked.sort();
        return ranked;
    }
    let mut picked: Vec<ViewId> = Vec::with_capacity(k);
    while picked.len() < k {
        let key = |v: ViewId| {
            let p = positions[v.index()];
            let spread = picked.iter().map(|q| (positions[q.index()] - p).length()).fold(f64::INFINITY, f64::min);
            ((p - centre).length(), spread)
        };
        let better = |a: (f64, f64), b: (f64, f64)| {
            if (a.0 - b.0).abs() > tie { a.0 > b.0 } else { a.1 > b.1 + tie }
        };
        let mut best: Option<(ViewId, (f64, f64))> = None;
        for v in views.clone().filter(|v| !picked.contains(v)) {
            let kv = key(v);
            if best.is_none_or(|(_, kb)| better(kv, kb)) {
                best = Some((v, kv));
            }
        }
        picked.push(best.expect("k is at most the number of views").0);
    }
    picked.sort();
    picked
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pts(v: &[(f64, f64)]) -> Vec<DVec2> {
        v.iter().map(|&(x, y)| DVec2::new(x, y)).collect()
    }

    #[test]
    fn degenerate_sets_converge() {
        // one point, two points, duplicates, collinear (even and odd), iterate on a data point
        let cases = [
            pts(&[(1.0, 2.0)]),
            pts(&[(0.0, 0.0), (2.0, 0.0)]),
            pts(&[(0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (5.0, 5.0)]),
            pts(&[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (3.0, 0.0)]),
            pts(&[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)]),
            pts(&[(0.0, 0.0), (1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)]), // centroid = point
        ];
        for points in cases {
            let m = geometric_median(&points).unwrap();
            assert!(m.point.is_finite(), "{points:?}");
            assert!(m.iterations < MAX_ITERATIONS, "{points:?} did not converge");
            let best = points.iter().map(|&p| weber_cost(&points, p)).fold(f64::INFINITY, f64::min);
            assert!(weber_cost(&points, m.point) <= best + 1e-9, "{points:?}: {m:?}");
        }
        assert_eq!(
            geometric_median(&pts(&[(0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (5.0, 5.0)])).unwrap().point,
            DVec2::ZERO
        );
        assert_eq!(geometric_median(&[]), None);
        assert_eq!(geometric_median(&pts(&[(f64::NAN, 0.0)])), None);
    }

    #[test]
    fn a_median_close_to_a_view_converges_quickly() {
        // Found by the property test: the median is 1.2e-4 from (0.21, 0.57) but not on it,
        // where plain Weiszfeld needs more than 10⁴ steps.
        let raw = [(20, -36), (-47, 40), (81, 82), (73, 65), (15, 80), (-9, 58), (-57, -65), (20, 87), (21, 57)];
        let points: Vec<DVec2> = raw.iter().map(|&(x, y)| DVec2::new(x as f64 * 0.01, y as f64 * 0.01)).collect();
        let m = geometric_median(&points).unwrap();
        assert!(m.iterations < 100, "{m:?}");
        let vertex = DVec2::new(0.21, 0.57);
        assert!((m.point - vertex).length() > 1e-5, "the optimum is off the view");
        assert!(weber_cost(&points, m.point) < weber_cost(&points, vertex));
    }

    #[test]
    fn baseline_sources_follow_the_paper() {
        let grid: Vec<DVec2> = (0..3).flat_map(|r| (0..4).map(move |c| DVec2::new(c as f64, -(r as f64)))).collect();
        let centre = DVec2::new(1.5, -1.0);
        assert_eq!(baseline_sources(&grid, centre, 2), vec![ViewId(0), ViewId(11)]);
        assert_eq!(baseline_sources(&grid, centre, 4), vec![ViewId(0), ViewId(3), ViewId(8), ViewId(11)]);
        assert_eq!(baseline_sources(&grid, centre, 1), vec![ViewId(5)]);
        let line: Vec<DVec2> = (0..100).map(|i| DVec2::new(i as f64 - 49.5, 0.0)).collect();
        assert_eq!(baseline_sources(&line, DVec2::ZERO, 2), vec![ViewId(0), ViewId(99)]);
        assert_eq!(baseline_sources(&line, DVec2::ZERO, 3), vec![ViewId(48), ViewId(49), ViewId(50)]);
    }
}
