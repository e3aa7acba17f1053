//! A kd-tree over `n` points of a fixed dimension, for k-nearest-neighbour queries.
//!
//! Used by the analysis (k-coherence similarity sets: ~65k-262k points of 8-16
//! dimensions, one query per point) and by the quality metrics (PCA-reduced
//! neighbourhoods). Construction splits each node at the median of its widest
//! dimension until leaves hold at most [`LEAF_SIZE`] points; the points are stored
//! reordered leaf by leaf (contiguous scans) together with their original indices.
//!
//! Queries are exact (depth-first, nearer child first, pruned with the incremental
//! lower bound of Arya & Mount) or approximate (best-bin-first with a budget of
//! examined points). [`KdTree::search`] exposes the best-bin-first traversal with a
//! caller-controlled bound, for searches that refine tree-space distances (lower
//! bounds) with a costlier exact distance. Results are deterministic: the same points and query always give
//! the same answer, ties in distance are broken by the smaller original index, and
//! nothing depends on threads or addresses.
//!
//! Squared distances are computed by [`squared_distance`] (four interleaved partial
//! sums, a fixed summation order), so a brute-force comparison that uses the same
//! function gets bit-identical distances.

use std::cell::RefCell;
use std::collections::BinaryHeap;

/// Largest number of points in a leaf (leaves hold between `LEAF_SIZE / 2` and
/// `LEAF_SIZE` points, except in trees smaller than that).
pub const LEAF_SIZE: usize = 12;

/// Marks a leaf in `Node::split_dim`.
const LEAF: u32 = u32::MAX;

#[derive(Clone, Copy, Debug, PartialEq)]
struct Node {
    /// Split dimension, or `LEAF`.
    split_dim: u32,
    /// Points of the left child have `p[split_dim] <= split`, of the right child `>=`.
    split: f32,
    /// Internal node: left child. Leaf: first point (in the reordered storage).
    a: u32,
    /// Internal node: right child. Leaf: one past the last point.
    b: u32,
}

/// A kd-tree over `len()` points of dimension `dim()`. See the module documentation.
#[derive(Clone, Debug)]
pub struct KdTree {
    dim: usize,
    /// Reordered points, row-major, `dim` floats each.
    points: Vec<f32>,
    /// Original index of each reordered point.
    index: Vec<u32>,
    nodes: Vec<Node>,
}

/// Squared Euclidean distance with a fixed summation order (four interleaved partial
/// sums, combined as `(s0 + s1) + (s2 + s3)`). This is the distance [`KdTree::knn`]
/// reports.
///
/// # Panics
/// If the slices differ in length.
#[inline]
pub fn squared_distance(a: &[f32], b: &[f32]) -> f32 {
    bounded_distance(a, b, f32::INFINITY)
}

/// [`squared_distance`], or any value `> bound` as soon as the partial sum exceeds
/// `bound` (partial sums never exceed the full sum, so this never rejects a distance
/// `<= bound`, and a distance `<= bound` is returned exactly).
#[inline(always)]
fn bounded_distance(a: &[f32], b: &[f32], bound: f32) -> f32 {
    assert_eq!(
        a.len(),
        b.len(),
        "squared_distance: slices differ in length"
    );
    let mut s = [0.0f32; 4];
    let mut ca = a.chunks_exact(4);
    let mut cb = b.chunks_exact(4);
    let mut done = 0usize;
    for (x, y) in (&mut ca).zip(&mut cb) {
        for l in 0..4 {
            let d = x[l] - y[l];
            s[l] += d * d;
        }
        done += 4;
        if done.is_multiple_of(16) && done < a.len() && (s[0] + s[1]) + (s[2] + s[3]) > bound {
            return f32::INFINITY;
        }
    }
    for (l, (x, y)) in ca.remainder().iter().zip(cb.remainder()).enumerate() {
        let d = x - y;
        s[l] += d * d;
    }
    (s[0] + s[1]) + (s[2] + s[3])
}

/// `(distance, index)` ordering used for results: ascending distance, then index.
#[inline(always)]
fn before(d: f32, i: u32, e: (f32, u32)) -> bool {
    d < e.0 || (d == e.0 && i < e.1)
}

/// The k best candidates so far, sorted ascending.
struct Best {
    k: usize,
    items: Vec<(f32, u32)>,
}

impl Best {
    fn new(k: usize) -> Self {
        Self {
            k,
            items: Vec::with_capacity(k + 1),
        }
    }

    /// Distance beyond which nothing can enter: the current k-th distance, or infinity
    /// while fewer than k are held.
    #[inline(always)]
    fn bound(&self) -> f32 {
        if self.items.len() < self.k {
            f32::INFINITY
        } else {
            self.items[self.k - 1].0
        }
    }

    /// Whether `(d, i)` would enter the list.
    #[inline(always)]
    fn admits(&self, d: f32, i: u32) -> bool {
        self.items.len() < self.k || before(d, i, self.items[self.k - 1])
    }

    #[inline]
    fn insert(&mut self, d: f32, i: u32) {
        let mut pos = self.items.len();
        while pos > 0 && before(d, i, self.items[pos - 1]) {
            pos -= 1;
        }
        self.items.insert(pos, (d, i));
        self.items.truncate(self.k);
    }
}

/// Whether a subtree with lower bound `rd` may hold something better than `bound`.
/// The incrementally updated bound carries float rounding, so it is relaxed slightly:
/// exact mode stays exact, at the price of rarely visiting a node for nothing.
#[inline(always)]
fn may_contain(rd: f32, bound: f32) -> bool {
    rd * (1.0 - 1e-5) <= bound
}

/// Per-thread scratch buffers for the best-bin-first search (taken out while in use, so
/// a predicate that itself queries a tree is fine).
#[derive(Default)]
struct Scratch {
    heap: BinaryHeap<std::cmp::Reverse<(u64, u32)>>,
    offsets: Vec<f32>,
    /// The current descent's farther children, not yet queued: `(heap key, split
    /// dimension, offset along it)`.
    pending: Vec<(u64, u32, f32)>,
    /// The popped bin's offsets.
    off: Vec<f32>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

impl KdTree {
    /// Builds the tree over `points` (row-major, `dim` floats per point; the number of
    /// points is `points.len() / dim`).
    ///
    /// # Panics
    /// If `dim == 0` while `points` is not empty, if `points.len()` is not a multiple of
    /// `dim`, or if there are `2^32` points or more.
    pub fn build(points: Vec<f32>, dim: usize) -> Self {
        Self::build_threaded(points, dim, 0)
    }

    /// [`Self::build`] on at most `threads` threads (0: all cores); the tree is the same
    /// for any thread count.
    pub fn build_threaded(points: Vec<f32>, dim: usize, threads: usize) -> Self {
        if points.is_empty() {
            return Self {
                dim,
                points,
                index: Vec::new(),
                nodes: Vec::new(),
            };
        }
        assert!(dim > 0, "KdTree::build: dim must be positive");
        assert!(
            points.len().is_multiple_of(dim),
            "KdTree::build: points.len() is not a multiple of dim"
        );
        let n = points.len() / dim;
        assert!(n < u32::MAX as usize, "KdTree::build: too many points");
        let mut perm: Vec<u32> = (0..n as u32).collect();
        let threads = super::resolve_threads(threads);
        // Subtrees split over the threads: 2^depth of them at once.
        let depth = threads.next_power_of_two().trailing_zeros().min(4);
        let nodes = build_tree(&points, dim, &mut perm, 0, depth);
        let mut reordered = Vec::with_capacity(points.len());
        for &p in &perm {
            let p = p as usize;
            reordered.extend_from_slice(&points[p * dim..(p + 1) * dim]);
        }
        Self {
            dim,
            points: reordered,
            index: perm,
            nodes,
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// Whether the tree holds no points.
    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }

    /// Dimension of the points.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// The point with original index `i`, if any (a linear search; for tests and
    /// diagnostics).
    pub fn point(&self, i: u32) -> Option<&[f32]> {
        let r = self.index.iter().position(|&j| j == i)?;
        Some(&self.points[r * self.dim..(r + 1) * self.dim])
    }

    /// The `k` nearest points to `query` among those with `accept(index) == true`, as
    /// `(squared distance, original index)`, ascending by distance then index
    /// (deterministic). Fewer than `k` only when fewer points are accepted.
    ///
    /// `max_checks`: approximate search in best-bin-first order that stops once this
    /// many points have been examined (whole leaves at a time; points the predicate
    /// rejects count) *and* `k` results are held; it also stops early when no remaining
    /// bin can improve the result, in which case the answer is exact. `0` = exact
    /// search.
    ///
    /// # Panics
    /// If `query.len() != self.dim()` (on a non-empty tree).
    pub fn knn(
        &self,
        query: &[f32],
        k: usize,
        max_checks: usize,
        accept: impl Fn(u32) -> bool,
    ) -> Vec<(f32, u32)> {
        if k == 0 || self.nodes.is_empty() {
            return Vec::new();
        }
        assert_eq!(
            query.len(),
            self.dim,
            "KdTree::knn: query has the wrong dimension"
        );
        let mut best = Best::new(k);
        if max_checks == 0 {
            let mut off = vec![0.0f32; self.dim];
            self.search_exact(0, 0.0, &mut off, query, &mut best, &accept);
        } else {
            let mut scratch = SCRATCH.with(|s| std::mem::take(&mut *s.borrow_mut()));
            let visit = |i: u32, d: f32| {
                if best.admits(d, i) && accept(i) {
                    best.insert(d, i);
                }
                best.bound()
            };
            self.search_bbf(query, f32::INFINITY, max_checks, visit, &mut scratch);
            SCRATCH.with(|s| *s.borrow_mut() = scratch);
        }
        best.items
    }

    #[inline(always)]
    fn scan_leaf(
        &self,
        start: usize,
        end: usize,
        query: &[f32],
        best: &mut Best,
        accept: &impl Fn(u32) -> bool,
    ) {
        let dim = self.dim;
        for r in start..end {
            let p = &self.points[r * dim..(r + 1) * dim];
            let d = bounded_distance(query, p, best.bound());
            let i = self.index[r];
            if best.admits(d, i) && accept(i) {
                best.insert(d, i);
            }
        }
    }

    fn search_exact(
        &self,
        node: u32,
        rd: f32,
        off: &mut [f32],
        query: &[f32],
        best: &mut Best,
        accept: &impl Fn(u32) -> bool,
    ) {
        let nd = self.nodes[node as usize];
        if nd.split_dim == LEAF {
            self.scan_leaf(nd.a as usize, nd.b as usize, query, best, accept);
            return;
        }
        let d = nd.split_dim as usize;
        let diff = query[d] - nd.split;
        let (near, far) = if diff < 0.0 {
            (nd.a, nd.b)
        } else {
            (nd.b, nd.a)
        };
        self.search_exact(near, rd, off, query, best, accept);
        let old = off[d];
        let far_rd = (rd - old * old + diff * diff).max(0.0);
        if may_contain(far_rd, best.bound()) {
            off[d] = diff;
            self.search_exact(far, far_rd, off, query, best, accept);
            off[d] = old;
        }
    }

    /// Best-bin-first traversal: bins in ascending order of their lower bound, points
    /// of a bin in storage order. `visit(index, d2)` is called for each point whose
    /// squared distance `d2` is `<= bound`, where `bound` is the value given, then the
    /// value the last `visit` returned. Stops when no remaining bin can hold a point
    /// within the bound, or once `max_checks` points have been examined (whole leaves
    /// at a time) and the bound is finite (`max_checks == 0`: no limit).
    ///
    /// With a `visit` that computes a more expensive distance for which the tree-space
    /// distance is a lower bound (e.g. full-dimensional distances over PCA-projected
    /// points) and returns the best such distance so far, this is an exact
    /// nearest-neighbour search in that distance when `max_checks == 0`.
    ///
    /// # Panics
    /// If `query.len() != self.dim()` (on a non-empty tree).
    pub fn search(
        &self,
        query: &[f32],
        bound: f32,
        max_checks: usize,
        visit: impl FnMut(u32, f32) -> f32,
    ) {
        if self.nodes.is_empty() {
            return;
        }
        assert_eq!(
            query.len(),
            self.dim,
            "KdTree::search: query has the wrong dimension"
        );
        let max_checks = if max_checks == 0 {
            usize::MAX
        } else {
            max_checks
        };
        let mut scratch = SCRATCH.with(|s| std::mem::take(&mut *s.borrow_mut()));
        self.search_bbf(query, bound, max_checks, visit, &mut scratch);
        SCRATCH.with(|s| *s.borrow_mut() = scratch);
    }

    fn search_bbf(
        &self,
        query: &[f32],
        bound: f32,
        max_checks: usize,
        mut visit: impl FnMut(u32, f32) -> f32,
        s: &mut Scratch,
    ) {
        let dim = self.dim;
        let mut bound = bound;
        s.heap.clear();
        s.offsets.clear();
        s.offsets.resize(dim, 0.0);
        s.off.clear();
        s.off.resize(dim, 0.0);
        // Heap key: (lower bound bits, node); bounds are >= 0, so the bits order like
        // the values; the node id breaks ties deterministically. Payload: offset slot.
        s.heap.push(std::cmp::Reverse((0u64, 0u32)));
        let mut checks = 0usize;
        while let Some(std::cmp::Reverse((key, slot))) = s.heap.pop() {
            let rd = f32::from_bits((key >> 32) as u32);
            if !may_contain(rd, bound) {
                break; // nothing left can improve the result: it is exact
            }
            if checks >= max_checks && bound < f32::INFINITY {
                break;
            }
            let mut node = (key & 0xffff_ffff) as u32;
            let slot = slot as usize;
            s.off
                .copy_from_slice(&s.offsets[slot * dim..(slot + 1) * dim]);
            // Descending to the nearer child keeps the lower bound (and the offsets);
            // the farther child has its own. Those are queued only if the search goes on
            // after this leaf: with a small budget most queries end at their first leaf,
            // and the heap pushes were most of their cost. Queued late or not, the heap
            // holds the same keys, so the order of the bins is the same.
            s.pending.clear();
            loop {
                let nd = self.nodes[node as usize];
                if nd.split_dim == LEAF {
                    for r in nd.a as usize..nd.b as usize {
                        let p = &self.points[r * dim..(r + 1) * dim];
                        let d = bounded_distance(query, p, bound);
                        if d <= bound {
                            bound = visit(self.index[r], d);
                        }
                    }
                    checks += (nd.b - nd.a) as usize;
                    break;
                }
                let d = nd.split_dim as usize;
                let diff = query[d] - nd.split;
                let (near, far) = if diff < 0.0 {
                    (nd.a, nd.b)
                } else {
                    (nd.b, nd.a)
                };
                let far_rd = (rd - s.off[d] * s.off[d] + diff * diff).max(0.0);
                if may_contain(far_rd, bound) {
                    let key = ((far_rd.to_bits() as u64) << 32) | far as u64;
                    s.pending.push((key, d as u32, diff));
                }
                node = near;
            }
            if checks >= max_checks && bound < f32::INFINITY {
                break; // the next pop would stop
            }
            for &(key, d, diff) in &s.pending {
                let new_slot = s.offsets.len() / dim;
                s.offsets.extend_from_slice(&s.off);
                s.offsets[new_slot * dim + d as usize] = diff;
                s.heap.push(std::cmp::Reverse((key, new_slot as u32)));
            }
        }
    }
}

/// How `perm` (original indices) is split: `None` for a leaf, else the widest dimension
/// (ties: the lowest), the split value and the left part's length; `perm` is reordered
/// so that the left part comes first (median by value, then by index).
fn split(
    points: &[f32],
    dim: usize,
    perm: &mut [u32],
    lo: &mut [f32],
    hi: &mut [f32],
) -> Option<(u32, f32, usize)> {
    let n = perm.len();
    if n <= LEAF_SIZE {
        return None;
    }
    lo.fill(f32::INFINITY);
    hi.fill(f32::NEG_INFINITY);
    for &p in perm.iter() {
        let row = &points[p as usize * dim..(p as usize + 1) * dim];
        for ((l, h), &v) in lo.iter_mut().zip(hi.iter_mut()).zip(row) {
            *l = l.min(v);
            *h = h.max(v);
        }
    }
    let mut split_dim = 0;
    let mut widest = f32::NEG_INFINITY;
    for d in 0..dim {
        let e = hi[d] - lo[d];
        if e > widest {
            widest = e;
            split_dim = d;
        }
    }
    let mid = n / 2;
    let key = |p: u32| points[p as usize * dim + split_dim];
    perm.select_nth_unstable_by(mid, |&a, &b| key(a).total_cmp(&key(b)).then(a.cmp(&b)));
    Some((split_dim as u32, key(perm[mid]), mid))
}

/// Builds the subtree over `perm` (original indices) and returns its node id; nodes are
/// numbered in preorder. `offset` is the position of `perm[0]` in the final ordering.
fn build_node(
    points: &[f32],
    dim: usize,
    perm: &mut [u32],
    offset: usize,
    nodes: &mut Vec<Node>,
    lo: &mut [f32],
    hi: &mut [f32],
) -> u32 {
    let id = nodes.len() as u32;
    let Some((split_dim, split, mid)) = split(points, dim, perm, lo, hi) else {
        nodes.push(Node {
            split_dim: LEAF,
            split: 0.0,
            a: offset as u32,
            b: (offset + perm.len()) as u32,
        });
        return id;
    };
    nodes.push(Node {
        split_dim,
        split,
        a: 0,
        b: 0,
    });
    let (left, right) = perm.split_at_mut(mid);
    let a = build_node(points, dim, left, offset, nodes, lo, hi);
    let b = build_node(points, dim, right, offset + mid, nodes, lo, hi);
    nodes[id as usize].a = a;
    nodes[id as usize].b = b;
    id
}

/// Subtrees of fewer points are built on one thread.
const PARALLEL_MIN_POINTS: usize = 1 << 14;

/// [`build_node`] of a whole (sub)tree, numbered from 0, with the two subtrees of each
/// of the top `depth` levels built on two threads: the same nodes as the sequential
/// build (the right subtree's ids are shifted past the left subtree's, as preorder
/// numbers them).
fn build_tree(
    points: &[f32],
    dim: usize,
    perm: &mut [u32],
    offset: usize,
    depth: u32,
) -> Vec<Node> {
    let (mut lo, mut hi) = (vec![0.0f32; dim], vec![0.0f32; dim]);
    let mut nodes = Vec::with_capacity(2 * perm.len().div_ceil(LEAF_SIZE / 2).max(1));
    if depth == 0 || perm.len() < PARALLEL_MIN_POINTS {
        build_node(points, dim, perm, offset, &mut nodes, &mut lo, &mut hi);
        return nodes;
    }
    let (split_dim, split, mid) = split(points, dim, perm, &mut lo, &mut hi)
        .expect("a subtree of PARALLEL_MIN_POINTS points is split");
    let (left, right) = perm.split_at_mut(mid);
    let (left, right) = std::thread::scope(|s| {
        let l = s.spawn(|| build_tree(points, dim, left, offset, depth - 1));
        let r = build_tree(points, dim, right, offset + mid, depth - 1);
        (l.join().expect("kd-tree build thread"), r)
    });
    let shift = |nd: &Node, by: u32| match nd.split_dim {
        LEAF => *nd,
        _ => Node {
            a: nd.a + by,
            b: nd.b + by,
            ..*nd
        },
    };
    nodes.push(Node {
        split_dim,
        split,
        a: 1,
        b: 1 + left.len() as u32,
    });
    nodes.extend(left.iter().map(|nd| shift(nd, 1)));
    nodes.extend(right.iter().map(|nd| shift(nd, 1 + left.len() as u32)));
    nodes
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic xorshift-style generator for test data.
    struct Rng(u64);
    impl Rng {
        fn next_u64(&mut self) -> u64 {
            // splitmix64
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        }
        fn f32(&mut self) -> f32 {
            (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    fn random_points(n: usize, dim: usize, seed: u64) -> Vec<f32> {
        let mut rng = Rng(seed);
        (0..n * dim).map(|_| rng.f32()).collect()
    }

    fn brute(
        points: &[f32],
        dim: usize,
        q: &[f32],
        k: usize,
        accept: impl Fn(u32) -> bool,
    ) -> Vec<(f32, u32)> {
        let mut all: Vec<(f32, u32)> = points
            .chunks_exact(dim)
            .enumerate()
            .filter(|(i, _)| accept(*i as u32))
            .map(|(i, p)| (squared_distance(q, p), i as u32))
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        all.truncate(k);
        all
    }

    /// The parallel build gives the sequential build's tree, node for node.
    #[test]
    fn parallel_build_is_the_sequential_one() {
        for (n, dim) in [(70_000, 8), (40_000, 3), (PARALLEL_MIN_POINTS, 4)] {
            let mut pts = random_points(n, dim, n as u64);
            // Repeated values: ties in the median are broken by index.
            for v in pts.iter_mut().step_by(5) {
                *v = (*v * 4.0).floor();
            }
            let mut seq_perm: Vec<u32> = (0..n as u32).collect();
            let (mut lo, mut hi) = (vec![0.0; dim], vec![0.0; dim]);
            let mut seq = Vec::new();
            build_node(&pts, dim, &mut seq_perm, 0, &mut seq, &mut lo, &mut hi);
            for depth in [1, 2, 3] {
                let mut perm: Vec<u32> = (0..n as u32).collect();
                let par = build_tree(&pts, dim, &mut perm, 0, depth);
                assert!(par == seq, "n {n}, dim {dim}, depth {depth}: nodes differ");
                assert!(
                    perm == seq_perm,
                    "n {n}, dim {dim}, depth {depth}: order differs"
                );
            }
        }
    }

    #[test]
    fn exact_matches_brute_force() {
        for &(n, dim) in &[
            (1usize, 3usize),
            (5, 2),
            (13, 1),
            (300, 4),
            (2000, 8),
            (1500, 16),
            (700, 24),
            (500, 7),
        ] {
            let pts = random_points(n, dim, 1 + n as u64 * 31 + dim as u64);
            let tree = KdTree::build(pts.clone(), dim);
            assert_eq!(tree.len(), n);
            assert_eq!(tree.dim(), dim);
            let queries = random_points(40, dim, 99 + dim as u64);
            for (qi, q) in queries.chunks_exact(dim).enumerate() {
                for &k in &[1usize, 2, 5, 17] {
                    let got = tree.knn(q, k, 0, |_| true);
                    assert_eq!(
                        got,
                        brute(&pts, dim, q, k, |_| true),
                        "n={n} dim={dim} k={k} q={qi}"
                    );
                    // With a predicate (odd indices only and one excluded region).
                    let acc = |i: u32| i % 2 == 1 && (i as usize) % 7 != qi % 7;
                    let got = tree.knn(q, k, 0, acc);
                    assert_eq!(
                        got,
                        brute(&pts, dim, q, k, acc),
                        "pred n={n} dim={dim} k={k}"
                    );
                    // An effectively unlimited budget makes best-bin-first exact too.
                    let got = tree.knn(q, k, usize::MAX, acc);
                    assert_eq!(
                        got,
                        brute(&pts, dim, q, k, acc),
                        "bbf n={n} dim={dim} k={k}"
                    );
                }
            }
            // Queries at the data points themselves, excluding the point.
            for i in (0..n).step_by((n / 20).max(1)) {
                let q = &pts[i * dim..(i + 1) * dim];
                let acc = |j: u32| j != i as u32;
                assert_eq!(tree.knn(q, 3, 0, acc), brute(&pts, dim, q, 3, acc));
            }
        }
    }

    #[test]
    fn search_with_refined_distance_is_exact() {
        // Tree over the first 4 of 10 coordinates (a lower bound of the full distance);
        // the visitor refines with the full distance.
        let (n, full_dim, dim) = (3000usize, 10usize, 4usize);
        let full = random_points(n, full_dim, 21);
        let proj: Vec<f32> = full
            .chunks_exact(full_dim)
            .flat_map(|p| p[..dim].to_vec())
            .collect();
        let tree = KdTree::build(proj, dim);
        let queries = random_points(100, full_dim, 22);
        let mut hits = 0;
        for q in queries.chunks_exact(full_dim) {
            let expect = brute(&full, full_dim, q, 1, |_| true)[0];
            for &checks in &[0usize, 300] {
                let mut best = (f32::INFINITY, u32::MAX);
                let mut visited = 0;
                tree.search(&q[..dim], f32::INFINITY, checks, |i, d| {
                    visited += 1;
                    let p = &full[i as usize * full_dim..(i as usize + 1) * full_dim];
                    let fd = squared_distance(q, p);
                    assert!(d <= fd * 1.0001 + 1e-6);
                    if before(fd, i, best) {
                        best = (fd, i);
                    }
                    best.0
                });
                assert!(visited < n);
                if checks == 0 {
                    assert_eq!(best, expect);
                } else {
                    hits += (best == expect) as usize;
                }
            }
        }
        println!("refined search, 300 checks: exact NN for {hits}/100 queries");
        assert!(hits >= 50, "{hits}/100");
        // A finite initial bound limits the visit to points within it.
        let q = &queries[..dim];
        let mut seen = Vec::new();
        tree.search(q, 0.01, 0, |i, d| {
            assert!(d <= 0.01);
            seen.push(i);
            0.01
        });
        seen.sort();
        let inside: Vec<u32> = tree_points_within(&full, full_dim, dim, q, 0.01);
        assert_eq!(seen, inside);
    }

    fn tree_points_within(
        full: &[f32],
        full_dim: usize,
        dim: usize,
        q: &[f32],
        r: f32,
    ) -> Vec<u32> {
        full.chunks_exact(full_dim)
            .enumerate()
            .filter(|(_, p)| squared_distance(&p[..dim], q) <= r)
            .map(|(i, _)| i as u32)
            .collect()
    }

    #[test]
    fn ties_and_duplicates_are_deterministic() {
        // Many identical points and a lattice with equal distances.
        let mut pts = vec![0.5f32; 50 * 3];
        for i in 0..10 {
            for j in 0..10 {
                pts.extend_from_slice(&[i as f32, j as f32, 0.0]);
            }
        }
        let tree = KdTree::build(pts.clone(), 3);
        for q in [
            [0.5f32, 0.5, 0.5],
            [4.5, 4.5, 0.0],
            [3.0, 3.0, 0.0],
            [-1.0, 20.0, 1.0],
        ] {
            for k in [1, 4, 9, 60] {
                assert_eq!(
                    tree.knn(&q, k, 0, |_| true),
                    brute(&pts, 3, &q, k, |_| true)
                );
                assert_eq!(
                    tree.knn(&q, k, usize::MAX, |_| true),
                    brute(&pts, 3, &q, k, |_| true)
                );
                let a = tree.knn(&q, k, 16, |_| true);
                assert_eq!(a, tree.knn(&q, k, 16, |_| true));
                assert_eq!(a.len(), k);
            }
        }
    }

    #[test]
    fn edge_cases() {
        let empty = KdTree::build(Vec::new(), 4);
        assert!(empty.is_empty());
        assert!(empty.knn(&[0.0; 4], 3, 0, |_| true).is_empty());
        assert!(empty.knn(&[0.0; 4], 3, 8, |_| true).is_empty());
        let pts = random_points(100, 2, 5);
        let tree = KdTree::build(pts.clone(), 2);
        assert!(tree.knn(&[0.3, 0.3], 0, 0, |_| true).is_empty());
        // Predicate rejecting everything, or all but two.
        assert!(tree.knn(&[0.3, 0.3], 3, 0, |_| false).is_empty());
        assert!(tree.knn(&[0.3, 0.3], 3, 4, |_| false).is_empty());
        let two = tree.knn(&[0.3, 0.3], 5, 4, |i| i == 17 || i == 80);
        assert_eq!(two.len(), 2);
        assert_eq!(two, brute(&pts, 2, &[0.3, 0.3], 5, |i| i == 17 || i == 80));
        // k larger than n.
        assert_eq!(tree.knn(&[0.3, 0.3], 1000, 0, |_| true).len(), 100);
        assert_eq!(tree.point(42), Some(&pts[84..86]));
        // Non-finite values must not panic.
        let weird = [
            f32::NAN,
            0.0,
            1.0,
            f32::INFINITY,
            0.5,
            0.5,
            0.2,
            f32::NEG_INFINITY,
        ];
        let t = KdTree::build(weird.repeat(5), 2);
        let _ = t.knn(&[0.5, 0.5], 3, 0, |_| true);
        let _ = t.knn(&[f32::NAN, 0.5], 3, 4, |_| true);
    }

    #[test]
    fn approximate_finds_the_nearest_usually() {
        let dim = 8;
        let n = 20000;
        let pts = random_points(n, dim, 7);
        let tree = KdTree::build(pts.clone(), dim);
        let queries = random_points(500, dim, 8);
        let mut hits = 0;
        for q in queries.chunks_exact(dim) {
            let exact = tree.knn(q, 1, 0, |_| true);
            let approx = tree.knn(q, 1, 64, |_| true);
            assert_eq!(approx.len(), 1);
            assert!(approx[0].0 >= exact[0].0);
            hits += (approx[0] == exact[0]) as usize;
        }
        println!("approximate (64 checks): exact NN for {hits}/500 queries");
        // Uniform random 8D data is the hard case for kd-trees; real neighbourhood data
        // is far more clustered.
        assert!(
            hits * 100 >= 500 * 60,
            "approximate search found the exact NN for only {hits}/500 queries"
        );
    }

    #[test]
    fn timing_65536_points_8d() {
        let dim = 8;
        let n = 65536;
        let pts = random_points(n, dim, 11);
        let t = std::time::Instant::now();
        let tree = KdTree::build(pts.clone(), dim);
        let build = t.elapsed();
        let mut report = format!("kdtree 65536x8D: build {:.1} ms", build.as_secs_f64() * 1e3);
        let mut means = Vec::new();
        for &checks in &[0usize, 64] {
            let t = std::time::Instant::now();
            let mut sum = 0.0f64;
            for i in 0..n {
                let q = &pts[i * dim..(i + 1) * dim];
                let r = tree.knn(q, 1, checks, |j| j != i as u32);
                sum += r[0].0 as f64;
            }
            let el = t.elapsed().as_secs_f64();
            report += &format!(
                ", {} queries k=1 max_checks={checks}: {:.1} ms ({:.2} us/query, mean d2 {:.4})",
                n,
                el * 1e3,
                el * 1e6 / n as f64,
                sum / n as f64
            );
            means.push(sum / n as f64);
        }
        println!("{report}");
        // Timing printed; asserted: the exact search (no budget) finds neighbours at
        // least as near as the bounded one, which still finds near ones.
        assert!(means[0] > 0.0 && means[0] <= means[1], "{means:?}");
        assert!(means[1] <= 2.0 * means[0], "{means:?}");
    }
}
