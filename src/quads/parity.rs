//! Segment counts of the feature curves such that every model face has an
//! even number of boundary segments.
//!
//! A triangulation of a face with `V_i` interior vertices, `V_b` boundary
//! vertices (as many as boundary segments) and Euler characteristic `χ` has
//! `T = 2 V_i + V_b − 2χ` triangles, so `T` is even exactly when `V_b` is:
//! recombination into quads needs an even `T` for a perfect matching. On the
//! graph whose nodes are the model faces plus an "outside" node and whose
//! edges are the curves, the set of curves whose count must change by one is
//! a T-join of the odd nodes; it is taken in a spanning forest of the cheapest
//! bumps (relative change of the segment length), fixing odd nodes from the
//! leaves up.

use serde::Serialize;

/// One curve whose segment count was changed to fix the parity.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CurveBump {
    /// The curve.
    pub curve: u32,
    /// Its length divided by the target size.
    pub target_segments: f64,
    /// Segment count before the bump.
    pub before: usize,
    /// Segment count after it.
    pub after: usize,
}

/// How the parity was reached.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ParityStats {
    /// Model faces with an odd number of boundary segments before the bumps.
    pub odd_faces_before: usize,
    /// The same after (0 unless a non-manifold curve made it impossible).
    pub odd_faces_after: usize,
    /// The curves bumped.
    pub bumps: Vec<CurveBump>,
}

/// A curve as the parity solver sees it.
#[derive(Debug, Clone)]
pub struct ParityCurve {
    /// Model faces it bounds: 1 entry for a boundary curve (the other side is
    /// outside), 2 for a curve between two faces; a curve with the same face
    /// on both sides or a non-manifold curve (3+ faces) is not bumped.
    pub faces: Vec<u32>,
    /// Length / target size.
    pub target: f64,
    /// Current segment count.
    pub segments: usize,
    /// Smallest allowed segment count.
    pub min_segments: usize,
    /// True when the same face lies on both sides (counts twice: no effect
    /// on parity).
    pub two_sided: bool,
    /// True when its count is fixed (its pieces are matched sides,
    /// [`super::sides`]): never bumped.
    pub fixed: bool,
}

/// Per node (model faces, then outside), the parity of its boundary segment count.
fn odd_nodes(curves: &[ParityCurve], n_faces: usize) -> Vec<bool> {
    let mut odd = vec![false; n_faces + 1];
    for c in curves.iter().filter(|c| !c.two_sided) {
        if c.segments % 2 == 1 {
            for &f in &c.faces {
                odd[f as usize] ^= true;
            }
            if c.faces.len() == 1 {
                odd[n_faces] ^= true;
            }
        }
    }
    odd
}

/// The cheaper bump of `c` (new count and relative change), if any.
fn best_bump(c: &ParityCurve) -> (usize, f64) {
    let target = c.target.max(1e-12);
    let up = (c.segments + 1, ((c.segments + 1) as f64 - c.target).abs() / target);
    if c.segments > c.min_segments {
        let down = (c.segments - 1, ((c.segments - 1) as f64 - c.target).abs() / target);
        if down.1 < up.1 {
            return down;
        }
    }
    up
}

/// Changes the segment counts of `curves` so every model face (of
/// `n_faces`) has an even number of boundary segments.
pub fn fix_parity(curves: &mut [ParityCurve], n_faces: usize) -> ParityStats {
    let before = odd_nodes(curves, n_faces);
    let odd_faces_before = before[..n_faces].iter().filter(|&&o| o).count();
    // Graph edges (node a, node b, curve), cheapest first (Kruskal).
    let outside = n_faces as u32;
    let mut edges: Vec<(f64, u32, u32, usize)> = curves
        .iter()
        .enumerate()
        .filter(|(_, c)| !c.two_sided && !c.fixed && (c.faces.len() == 1 || c.faces.len() == 2))
        .map(|(i, c)| {
            let b = if c.faces.len() == 2 { c.faces[1] } else { outside };
            (best_bump(c).1, c.faces[0], b, i)
        })
        .collect();
    edges.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.3.cmp(&y.3)));
    let n_nodes = n_faces + 1;
    let mut parent: Vec<usize> = (0..n_nodes).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    let mut adjacency: Vec<Vec<(usize, usize)>> = vec![Vec::new(); n_nodes];
    for &(_, a, b, i) in &edges {
        let (ra, rb) = (find(&mut parent, a as usize), find(&mut parent, b as usize));
        if ra != rb {
            parent[ra] = rb;
            adjacency[a as usize].push((b as usize, i));
            adjacency[b as usize].push((a as usize, i));
        }
    }
    // Depth-first order of each tree, then fix odd nodes from the leaves up.
    let mut odd = before;
    let mut seen = vec![false; n_nodes];
    let mut bumps = Vec::new();
    for root in 0..n_nodes {
        if seen[root] {
            continue;
        }
        seen[root] = true;
        let mut order = vec![(root, usize::MAX, usize::MAX)];
        let mut k = 0;
        while k < order.len() {
            let (v, _, _) = order[k];
            for &(w, c) in &adjacency[v] {
                if !seen[w] {
                    seen[w] = true;
                    order.push((w, v, c));
                }
            }
            k += 1;
        }
        for &(v, up, c) in order.iter().skip(1).rev() {
            if odd[v] {
                let curve = &mut curves[c];
                let (after, _) = best_bump(curve);
                bumps.push(CurveBump { curve: c as u32, target_segments: curve.target, before: curve.segments, after });
                curve.segments = after;
                odd[v] = false;
                odd[up] ^= true;
            }
        }
    }
    bumps.sort_by_key(|b| b.curve);
    let after = odd_nodes(curves, n_faces);
    ParityStats { odd_faces_before, odd_faces_after: after[..n_faces].iter().filter(|&&o| o).count(), bumps }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(faces: &[u32], target: f64) -> ParityCurve {
        ParityCurve {
            faces: faces.to_vec(),
            target,
            segments: (target.round() as usize).max(1),
            min_segments: 1,
            two_sided: false,
            fixed: false,
        }
    }

    #[test]
    fn a_single_odd_boundary_curve_is_bumped_towards_its_target() {
        let mut c = vec![curve(&[0], 11.2)];
        let s = fix_parity(&mut c, 1);
        assert_eq!(s.odd_faces_before, 1);
        assert_eq!(s.odd_faces_after, 0);
        assert_eq!(c[0].segments, 12);
        assert_eq!(s.bumps, vec![CurveBump { curve: 0, target_segments: 11.2, before: 11, after: 12 }]);
        let mut c = vec![curve(&[0], 10.8)];
        fix_parity(&mut c, 1);
        assert_eq!(c[0].segments, 10);
    }

    #[test]
    fn two_odd_faces_are_fixed_by_the_cheapest_path_between_them() {
        // Faces 0 and 1 share a long curve (cheap bump) and each has a short
        // boundary curve; 0 and 1 are odd, outside is even.
        let mut c = vec![curve(&[0, 1], 101.0), curve(&[0], 2.0), curve(&[1], 2.0)];
        let s = fix_parity(&mut c, 2);
        assert_eq!(s.odd_faces_before, 2);
        assert_eq!(s.odd_faces_after, 0);
        assert_eq!(s.bumps.len(), 1);
        assert_eq!(s.bumps[0].curve, 0);
    }

    #[test]
    fn even_faces_need_no_bump() {
        // A cube: 6 faces, 12 curves each between two faces, 3 segments each.
        let pairs = [(0, 1), (0, 2), (0, 3), (0, 4), (5, 1), (5, 2), (5, 3), (5, 4), (1, 2), (2, 3), (3, 4), (4, 1)];
        let mut c: Vec<ParityCurve> = pairs.iter().map(|&(a, b)| curve(&[a, b], 3.0)).collect();
        let s = fix_parity(&mut c, 6);
        assert_eq!(s.odd_faces_before, 0);
        assert!(s.bumps.is_empty());
    }
}
