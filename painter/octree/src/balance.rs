//! Face neighbours, refinement with 2:1 face balance, and the balance test
//! for coarsening (spec 3.1, 4.2, 4.3). Reference twin:
//! reference/octopaint_ref/tree.py (`refine_round`, `balance_allows_coarsen`).
//!
//! The reference refines a round in one batch; here a round is the
//! sequential definition of spec 4.2 (candidates in ascending index order,
//! each refining its coarser face-neighbour leaves first, recursively),
//! which the spec proves allocates exactly the same units in the same order.

use crate::lattice::FACES;
use crate::pool::{NONE, Refusal, Tree, UNIT};

/// The deepest a tree can be, plus one: bounds the climb of a neighbour search.
const MAX_PATH: usize = 32;

/// A face neighbour not looked up yet.
const UNKNOWN: u32 = NONE - 1;

/// A parent's same-depth-or-coarser face neighbours, each looked up when a
/// child first needs it ([`Tree::refine_balanced_with`]).
struct ParentFaces {
    parent: u32,
    nb: [u32; 6],
}

impl ParentFaces {
    const NONE: ParentFaces = ParentFaces { parent: NONE, nb: [UNKNOWN; 6] };
}

/// Face `f` of non-root cell `c` is inward: across it lies `c`'s sibling
/// (its octant bit on the face's axis points into the parent).
#[inline]
fn faces_sibling(c: u32, f: usize) -> bool {
    let (a, s) = FACES[f];
    (s > 0) == ((c >> a) & 1 == 0)
}

impl Tree {
    /// The cell of greatest depth `<= depth(c)` across face `f` of live
    /// cell `c` (its same-depth-or-coarser face neighbour), or NONE at the
    /// canvas boundary. Climbs while the face is outward, steps to the
    /// sibling (or the neighbouring root), then mirrors the climb back down
    /// while children exist: the g3 walk of spec 3.3, for any face.
    pub fn neighbour(&self, c: u32, f: usize) -> u32 {
        let a = FACES[f].0;
        let mut path = [0u32; MAX_PATH];
        let mut n = 0;
        let mut x = c;
        let mut y;
        loop {
            if self.depth[x as usize] == 0 {
                match self.lat.root_neighbour(x, f) {
                    Some(r) => y = r,
                    None => return NONE,
                }
                break;
            }
            if faces_sibling(x, f) {
                y = x ^ (1 << a);
                break;
            }
            path[n] = x & 7;
            n += 1;
            x = self.parent[x as usize];
        }
        while n > 0 {
            let fc = self.first_child[y as usize];
            if fc == NONE {
                break;
            }
            n -= 1;
            y = fc + (path[n] ^ (1 << a));
        }
        y
    }

    /// Refine leaf `l` after refining, recursively and in face order, every
    /// coarser face-neighbour leaf (spec 4.2). `new_units` receives the
    /// units in allocation order, each with its parent.
    fn refine_balanced(&mut self, l: u32, new_units: &mut Vec<(u32, u32)>) -> Result<(), Refusal> {
        let mut faces = ParentFaces::NONE;
        self.refine_balanced_with(l, new_units, &mut faces)
    }

    /// [`Tree::refine_balanced`], the outward face neighbours of `l` found
    /// through `faces`, its parent's face neighbours: consecutive candidates
    /// are often siblings, and a child's neighbour across an outward face is
    /// its parent's neighbour, or that neighbour's child facing it (the last
    /// step of [`Tree::neighbour`]'s descent). A parent's neighbour is
    /// looked up once for all its children. In a balanced tree a parent's
    /// neighbours are as deep as it is (its children are, or lie over,
    /// leaves one level deeper), so refining leaves for balance changes no
    /// such lookup; the lookups are dropped after one all the same.
    fn refine_balanced_with(&mut self, l: u32, new_units: &mut Vec<(u32, u32)>, faces: &mut ParentFaces) -> Result<(), Refusal> {
        let d = self.depth[l as usize];
        if d > 0 {
            let p = self.parent[l as usize];
            if faces.parent != p {
                *faces = ParentFaces { parent: p, nb: [UNKNOWN; 6] };
            }
        }
        for f in 0..6 {
            // Across an inward face lies the sibling, as deep as `l`: only
            // the outward faces can hold a coarser leaf.
            if d > 0 && faces_sibling(l, f) {
                continue;
            }
            let nb = if d > 0 && faces.parent != NONE {
                if faces.nb[f] == UNKNOWN {
                    faces.nb[f] = self.neighbour(faces.parent, f);
                }
                self.step_down(faces.nb[f], d - 1, l, f)
            } else {
                self.neighbour(l, f)
            };
            if nb != NONE && self.depth[nb as usize] < d && self.first_child[nb as usize] == NONE {
                *faces = ParentFaces::NONE;
                self.refine_balanced(nb, new_units)?;
            }
        }
        let unit = self.allocate_unit()?;
        self.make_children(l, unit);
        new_units.push((l, unit));
        Ok(())
    }

    /// The face neighbour of `c` across outward face `f` from its parent's,
    /// `y` (the parent at depth `dp`): `y`'s child facing `c` when `y` is as
    /// deep as the parent and has children, else `y` itself.
    #[inline]
    fn step_down(&self, y: u32, dp: u8, c: u32, f: usize) -> u32 {
        if y == NONE || self.depth[y as usize] != dp {
            return y;
        }
        match self.first_child[y as usize] {
            NONE => y,
            fc => fc + ((c & 7) ^ (1 << FACES[f].0)),
        }
    }

    /// One round (spec 4.2): refine every candidate leaf, ascending, with
    /// balance. Returns the new units (parent, unit) in allocation order and
    /// the refusal that stopped the round, if any; the refinements before it
    /// stand (every prefix of the order keeps balance).
    pub fn refine_round(&mut self, candidates: &mut Vec<u32>) -> (Vec<(u32, u32)>, Option<Refusal>) {
        candidates.sort_unstable();
        candidates.dedup();
        let (units, _, refusal) = self.refine_candidates(candidates, usize::MAX);
        (units, refusal)
    }

    /// Part of a round: refine the candidates of `sorted` (ascending, each
    /// once) in order until at least `max_units` units are allocated or the
    /// list ends. Returns the new units, how many candidates were consumed,
    /// and the refusal that stopped it. Calling it on consecutive parts of
    /// a round's sorted candidates refines exactly what one call on the
    /// whole list does, in the same order: the round's order is sequential
    /// (spec 4.2), and no cell made in a round is refined later in it.
    pub fn refine_candidates(&mut self, sorted: &[u32], max_units: usize) -> (Vec<(u32, u32)>, usize, Option<Refusal>) {
        let mut new_units = Vec::new();
        let mut faces = ParentFaces::NONE;
        for (i, &l) in sorted.iter().enumerate() {
            if new_units.len() >= max_units {
                return (new_units, i, None);
            }
            if self.first_child[l as usize] != NONE {
                continue; // refined earlier in the round, for balance
            }
            if let Err(r) = self.refine_balanced_with(l, &mut new_units, &mut faces) {
                return (new_units, i + 1, Some(r));
            }
        }
        (new_units, sorted.len(), None)
    }

    /// For a cell X whose neighbour across X's face `f` is `m` (same depth,
    /// with children): the 4 children of `m` that touch X (spec 3.4; octant
    /// bit `a` = 0 when `m` lies on X's +a side, 1 on its −a side).
    #[inline]
    pub fn facing_children(&self, m: u32, f: usize) -> [u32; 4] {
        let (a, s) = FACES[f];
        let fc = self.first_child[m as usize];
        let side = if s > 0 { 0 } else { 1 };
        let mut out = [NONE; 4];
        let mut i = 0;
        for k in 0..UNIT {
            if (k >> a) & 1 == side {
                out[i] = fc + k;
                i += 1;
            }
        }
        out
    }

    /// The same-depth face neighbour of `c` across `f` that has children,
    /// or NONE.
    #[inline]
    pub fn internal_same_depth_neighbour(&self, c: u32, f: usize) -> u32 {
        let nb = self.neighbour(c, f);
        if nb != NONE && self.depth[nb as usize] == self.depth[c as usize] && self.first_child[nb as usize] != NONE { nb } else { NONE }
    }

    /// Collapsing `p`'s children keeps 2:1 balance (spec 4.3): every child
    /// of an internal same-depth face neighbour that faces `p` is a leaf.
    pub fn balance_allows_coarsen(&self, p: u32) -> bool {
        (0..6).all(|f| {
            let m = self.internal_same_depth_neighbour(p, f);
            m == NONE || self.facing_children(m, f).iter().all(|&k| self.first_child[k as usize] == NONE)
        })
    }

    /// All 8 children of `p` are leaves and all empty or all identical
    /// (equal rgb bytes and equal f32 sigma; spec 9).
    pub fn mergeable(&self, p: u32) -> bool {
        let fc = self.first_child[p as usize];
        if fc == NONE {
            return false;
        }
        let kids = fc as usize..(fc + UNIT) as usize;
        if self.first_child[kids.clone()].iter().any(|&g| g != NONE) {
            return false;
        }
        let sig = &self.sigma[kids.clone()];
        let rgb = &self.rgb[kids];
        sig.iter().all(|&s| s == 0.0) || (sig.iter().all(|&s| s == sig[0]) && rgb.iter().all(|&c| c == rgb[0]))
    }

    /// Mergeable and balance allows the collapse (spec 9).
    pub fn collapsible(&self, p: u32) -> bool {
        self.mergeable(p) && self.balance_allows_coarsen(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use octopaint_model::Canvas;

    /// Random rounds over random leaves (runs of siblings among them, as
    /// the paint pass gives them): the refinements with each parent's
    /// neighbours looked up once are those of a search from each leaf
    /// (balance holds after every round, and `step_down` from the parent's
    /// neighbour is `neighbour` itself on every outward face of the tree).
    #[test]
    fn a_parents_neighbours_give_its_childrens() {
        // Marsaglia's xorshift32: any spread of cells will do.
        let mut seed = 5u32;
        let mut next = |n: u32| {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed % n
        };
        for roots in [[1, 1, 1], [2, 1, 3]] {
            let mut tree = Tree::new(&Canvas { roots, max_depth: 9, root_size: 1.0, capacity: 1 << 22 });
            let mut checked = 0;
            for _ in 0..12 {
                let leaves: Vec<u32> = (0..tree.n_used())
                    .filter(|&c| tree.depth[c as usize] != crate::pool::FREE && tree.is_leaf(c) && u32::from(tree.depth[c as usize]) < 8)
                    .collect();
                let mut cand = Vec::new();
                for _ in 0..(1 + leaves.len() / 6).min(300) {
                    let l = leaves[next(leaves.len() as u32) as usize];
                    // Its siblings too, now and then.
                    if tree.depth[l as usize] > 0 && next(2) == 0 {
                        cand.extend((l & !7..(l & !7) + UNIT).filter(|&s| tree.is_leaf(s)));
                    } else {
                        cand.push(l);
                    }
                }
                let (_, refusal) = tree.refine_round(&mut cand);
                assert!(refusal.is_none(), "{refusal:?} at {} cells", tree.n_used());
                for c in 0..tree.n_used() {
                    let d = tree.depth[c as usize];
                    if d == crate::pool::FREE || d == 0 {
                        continue;
                    }
                    let p = tree.parent[c as usize];
                    for f in 0..6 {
                        if faces_sibling(c, f) {
                            continue;
                        }
                        let nb = tree.neighbour(c, f);
                        assert_eq!(tree.step_down(tree.neighbour(p, f), d - 1, c, f), nb, "cell {c} face {f}");
                        // 2:1 balance across the face.
                        if nb != NONE && tree.is_leaf(c) {
                            assert!(tree.depth[nb as usize] + 1 >= d, "cell {c} face {f}: neighbour {nb} too coarse");
                        }
                        checked += 1;
                    }
                }
            }
            assert!(checked > 20_000, "{checked} faces");
        }
    }
}
