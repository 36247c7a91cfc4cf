//! The BVH build for scenes with many triangles at one place (a common bad export: a mesh
//! duplicated onto itself thousands of times).
//!
//! obvhs's PLOC merges a pair of clusters only when each is the other's cheapest neighbour, and
//! breaks ties of equal cost towards the right. Clusters with equal bounds (triangles with one
//! centroid) all cost the same, so only the last pair of such a run agrees, one merge per pass
//! over every cluster: 10,000 coincident triangles took 3.4 s, 200,000 more than a minute.
//! Here the triangles are grouped by centroid first, PLOC builds over one bounding box per
//! group, and each group's leaf is then expanded into a balanced subtree of its triangles (split
//! at the middle index), which costs O(n log n) whatever the duplication.

use std::collections::HashMap;

use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::ploc::PlocBuilder;

/// Groups larger than this take the grouped build; below it PLOC's extra passes stay few (one
/// per member of the largest group), and ordinary scenes keep obvhs's own build unchanged.
pub const LARGEST_PLAIN_GROUP: usize = 32;

/// Triangle indices grouped by the exact bits of their bounding-box centre, in order of each
/// group's first triangle (deterministic).
pub fn centroid_groups(aabbs: &[Aabb]) -> Vec<Vec<u32>> {
    let mut group_of: HashMap<[u32; 3], usize> = HashMap::new();
    let mut groups: Vec<Vec<u32>> = Vec::new();
    for (i, aabb) in aabbs.iter().enumerate() {
        let key = aabb.center().to_array().map(f32::to_bits);
        let g = *group_of.entry(key).or_insert_with(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[g].push(i as u32);
    }
    groups
}

fn union_of(members: &[u32], aabbs: &[Aabb]) -> Aabb {
    members.iter().fold(Aabb::empty(), |a, &m| a.union(&aabbs[m as usize]))
}

/// Builds the CWBVH over `aabbs` (one per triangle) as obvhs's `build_cwbvh_from_tris` does
/// without pre-splitting (PLOC, reinsertion, conversion), but with PLOC over `groups`.
pub fn build_grouped(aabbs: &[Aabb], groups: &[Vec<u32>], params: &BvhBuildParams) -> CwBvh {
    let group_aabbs: Vec<Aabb> = groups.iter().map(|g| union_of(g, aabbs)).collect();
    let mut bvh2: Bvh2 = PlocBuilder::with_capacity(groups.len()).build(
        params.ploc_search_distance,
        &group_aabbs,
        (0..groups.len() as u32).collect::<Vec<_>>(),
        params.sort_precision,
        params.search_depth_threshold,
    );
    let mut primitive_indices = Vec::with_capacity(aabbs.len());
    // Only PLOC's own nodes: the expansion appends the subtrees' nodes after them.
    for node in 0..bvh2.nodes.len() {
        if bvh2.nodes[node].is_leaf() {
            let group = bvh2.primitive_indices[bvh2.nodes[node].first_index as usize] as usize;
            expand(&mut bvh2.nodes, node, &groups[group], aabbs, &mut primitive_indices);
        }
    }
    bvh2.primitive_indices = primitive_indices;
    // The caches PLOC filled describe the tree before the expansion: let obvhs recompute them.
    bvh2.parents.clear();
    bvh2.primitives_to_nodes.clear();
    bvh2.children_are_ordered_after_parents = false;
    let largest = groups.iter().map(Vec::len).max().unwrap_or(1);
    bvh2.max_depth += largest.next_power_of_two().trailing_zeros() as usize + 1;
    ReinsertionOptimizer::default().run(&mut bvh2, params.reinsertion_batch_ratio, None);
    bvh2_to_cwbvh(&bvh2, params.max_prims_per_leaf.clamp(1, 3), true, false)
}

/// Turns `node` into a balanced subtree over `members`: a leaf (one triangle, as PLOC makes
/// them) for one member, else an inner node over the two halves.
fn expand(nodes: &mut Vec<Bvh2Node>, node: usize, members: &[u32], aabbs: &[Aabb], primitives: &mut Vec<u32>) {
    if let [only] = members {
        nodes[node] = Bvh2Node::new(aabbs[*only as usize], 1, primitives.len() as u32);
        primitives.push(*only);
        return;
    }
    let first = nodes.len();
    nodes.extend([Bvh2Node::default(); 2]);
    nodes[node] = Bvh2Node::new(union_of(members, aabbs), 0, first as u32);
    let (left, right) = members.split_at(members.len() / 2);
    expand(nodes, first, left, aabbs, primitives);
    expand(nodes, first + 1, right, aabbs, primitives);
}
