//! A maximum matching of calls to what answers them (a reply, a request): one answers one call.

use std::collections::{BTreeMap, BTreeSet};

/// A maximum matching by augmenting paths (Kuhn): `edges[i]` lists the items call `i` may be
/// matched with. Returns each matched item's call. It gives every call an item of its own
/// whenever that is possible at all, which a greedy pass does not: it may hand a call the only
/// item another call fits while the first had another. Deterministic (the order of `edges`).
pub fn maximum<K: Ord + Copy>(edges: &[Vec<K>]) -> BTreeMap<K, usize> {
    fn augment<K: Ord + Copy>(
        i: usize,
        edges: &[Vec<K>],
        owner: &mut BTreeMap<K, usize>,
        seen: &mut BTreeSet<K>,
    ) -> bool {
        for &e in &edges[i] {
            if !seen.insert(e) {
                continue;
            }
            let free = match owner.get(&e) {
                None => true,
                Some(&other) => augment(other, edges, owner, seen),
            };
            if free {
                owner.insert(e, i);
                return true;
            }
        }
        false
    }
    let mut owner = BTreeMap::new();
    for i in 0..edges.len() {
        augment(i, edges, &mut owner, &mut BTreeSet::new());
    }
    owner
}
