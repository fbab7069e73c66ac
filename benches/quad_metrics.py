#!/usr/bin/env python3
"""Quad-mesh metrics of any MSH file, computed the same way for every tool.

Usage: python3 benches/quad_metrics.py [--sharp-angle DEG] FILE.msh...

The bench (`cargo bench --bench pipeline -- --gmsh --stages quads`) runs it
on meshatlas's `quads.msh` and on Gmsh's quasi-structured output, so both
sides' numbers come from one definition. Reading goes through the gmsh
Python API (any MSH version, ASCII or binary, order 1 or 2); only the corner
nodes of each element are used.

Prints one JSON object per file, one line each:
  file, n_nodes, n_vertices (corners of 2D elements), n_quads, n_triangles,
  n_other (other 2D elements), n_curve_edges (edges of line elements),
  euler_characteristic (V - E + F of the 2D elements), index_sum
  (sum over vertices off the open boundary of 4 - valence, plus over open
  boundary vertices of 2 - incident elements: 4 chi for a pure quad mesh),
  valence_histogram_interior {valence: count},
  irregular_interior: vertices on no curve and no open boundary whose
    valence (edge count) is not 4,
  irregular_boundary: vertices on a curve (a line element's edge) or on the
    open boundary, corner-aware: the elements around the vertex are split
    into sectors at the curve and boundary edges; a sector of total corner
    angle A (in 3D) should hold max(1, round(A / 90 deg)) elements, and the
    vertex is irregular when one sector does not (a 90 deg corner with one
    quad, a straight boundary with two, a cube corner with three quads in
    three sectors, and a smooth seam with two and two are all regular),
  irregular = irregular_interior + irregular_boundary,
  sj_min, sj_mean, sj_p5, sj_frac_ge_0_5, sj_below_0_3, inverted_sj:
    the scaled Jacobian of each quad (min over its corners of
    (e_next x e_prev) . n / (|e_next| |e_prev|), Verdict's definition against
    a reference normal n, like meshatlas's quads::jacobian) with n the unit
    normal of the surface under the quad estimated from the mesh alone: the
    sum of the unit normals of the quad and of its neighbours across edges
    that are on no curve and not sharp (an angle between the two normals in
    (SHARP, 180 - SHARP) deg, SHARP = --sharp-angle, default 40 like the
    atlas, or beyond 180 - SHARP at a knife-edge ridge, where each normal
    points away from the other element: the two sides of a sharp tip); a
    quad folded over its neighbours (normal at about 180 deg, pointing
    towards them) thus counts as inverted (sj <= 0),
  sicn_min, sicn_mean, inverted_sicn: Gmsh's own minSICN quality
    (getElementQualities), inverted when <= 0,
  max_angle_deviation_deg: largest |corner angle - 90| over the quads,
  mean_edge_length: over the unique edges of the 2D elements.
"""
import json
import math
import sys

import gmsh
import numpy as np

# How far (sine of the angle) each side of a knife-edge ridge must point
# away from the other: below it, two elements with opposite normals are a
# fold.
RIDGE = 0.05


def load(path):
    """Nodes (n, 3), corner lists of quads and triangles (index arrays into
    the nodes), their Gmsh element tags, the curve edges (m, 2) and the
    node count."""
    gmsh.clear()
    gmsh.open(path)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    tags = np.asarray(tags, dtype=np.int64)
    xyz = np.asarray(coords, dtype=float).reshape(-1, 3)
    index = np.full(int(tags.max()) + 1 if len(tags) else 1, -1, dtype=np.int64)
    index[tags] = np.arange(len(tags))
    polys = {3: [], 4: []}
    elem_tags = {3: [], 4: []}
    n_other = 0
    curve_edges = []
    for dim in (1, 2):
        for etype, etags, enodes in zip(*gmsh.model.mesh.getElements(dim)):
            _, _, _, n_nodes, _, n_primary = gmsh.model.mesh.getElementProperties(etype)
            nodes = index[np.asarray(enodes, dtype=np.int64)].reshape(-1, n_nodes)[:, :n_primary]
            if dim == 1:
                curve_edges.append(nodes[:, :2])
            elif n_primary in polys:
                polys[n_primary].append(nodes)
                elem_tags[n_primary].append(np.asarray(etags, dtype=np.int64))
            else:
                n_other += len(etags)
    cat = lambda xs, k: np.concatenate(xs) if xs else np.zeros((0, k) if k else 0, dtype=np.int64)
    return {
        "xyz": xyz,
        "quads": cat(polys[4], 4),
        "tris": cat(polys[3], 3),
        "quad_tags": cat(elem_tags[4], 0),
        "curve_edges": cat(curve_edges, 2),
        "n_other": n_other,
        "n_nodes": len(tags),
    }


def corner_table(xyz, quads, tris):
    """Every element corner as (element, vertex, next vertex, previous
    vertex, local index); triangles are numbered after the quads."""
    rows = []
    for off, elems in ((0, quads), (len(quads), tris)):
        k = elems.shape[1]
        for i in range(k):
            e = np.arange(len(elems)) + off
            rows.append(np.stack([e, elems[:, i], elems[:, (i + 1) % k], elems[:, (i - 1) % k], np.full(len(elems), i)], 1))
    return np.concatenate(rows) if rows else np.zeros((0, 5), dtype=np.int64)


def corner_angles(xyz, corners):
    """Unsigned angle (radians) of each corner between its two edges."""
    a = xyz[corners[:, 2]] - xyz[corners[:, 1]]
    b = xyz[corners[:, 3]] - xyz[corners[:, 1]]
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))


def edge_keys(a, b, n):
    """Undirected edge key of vertex pairs."""
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    return lo * n + hi


def unit(v):
    """Rows of `v` scaled to unit length (zero rows left zero)."""
    length = np.linalg.norm(v, axis=1)
    return v / np.where(length > 0, length, 1.0)[:, None]


def element_normals(xyz, quads, tris):
    """Unit normals of the quads (cross product of their diagonals) then of
    the triangles."""
    p, t = xyz[quads], xyz[tris]
    return unit(np.concatenate([np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1]), np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])]))


def element_centroids(xyz, quads, tris):
    """Centroids of the quads' corners, then of the triangles'."""
    return np.concatenate([xyz[quads].mean(axis=1), xyz[tris].mean(axis=1)])


def knife_edge(xyz, centroids, normals, lo, hi, e1, e2):
    """Whether each edge lo-hi between elements e1 and e2 whose normals are
    about opposite is a knife-edge ridge (the two sides of a sharp tip)
    rather than one element folded over the other. With d1, d2 the unit
    directions from the edge into each element, across the edge, each
    element's normal points away from the other element at a ridge
    (n1 . d2 < 0 and n2 . d1 < 0), while a folded element's normal points
    towards it (or lies flat: n . d = 0)."""
    t = unit(xyz[hi] - xyz[lo])

    def into(e):
        d = centroids[e] - xyz[lo]
        return unit(d - t * np.einsum("ij,ij->i", d, t)[:, None])

    d1, d2 = into(e1), into(e2)
    return (np.einsum("ij,ij->i", normals[e1], d2) < -RIDGE) & (np.einsum("ij,ij->i", normals[e2], d1) < -RIDGE)


class Edges:
    """The unique edges of the 2D elements: endpoints, use counts, the two
    elements of each edge used twice, whether it is on a curve and whether
    it is sharp."""

    def __init__(self, xyz, corners, normals, centroids, curve_edges, sharp_deg):
        nv = len(xyz)
        keys = edge_keys(corners[:, 1], corners[:, 2], nv)
        self.keys, self.inverse, self.uses = np.unique(keys, return_inverse=True, return_counts=True)
        self.inverse = self.inverse.reshape(-1)
        self.lo, self.hi = self.keys // nv, self.keys % nv
        curve_keys = edge_keys(curve_edges[:, 0], curve_edges[:, 1], nv)
        self.curve = np.isin(self.keys, curve_keys)
        # the two elements of every edge used exactly twice
        order = np.argsort(self.inverse, kind="stable")
        first = np.searchsorted(self.inverse[order], np.arange(len(self.keys)))
        self.twice = np.nonzero(self.uses == 2)[0]
        self.e1 = corners[order[first[self.twice]], 0]
        self.e2 = corners[order[first[self.twice] + 1], 0]
        cos = np.einsum("ij,ij->i", normals[self.e1], normals[self.e2])
        lim = math.cos(math.radians(sharp_deg))
        # a fold (normals about opposite) is an inverted element, not a
        # feature, unless it is a knife-edge ridge (a sharp tip's two sides)
        self.sharp = np.zeros(len(self.keys), dtype=bool)
        ridge = knife_edge(xyz, centroids, normals, self.lo[self.twice], self.hi[self.twice], self.e1, self.e2)
        self.sharp[self.twice] = (np.abs(cos) < lim) | ((cos <= -lim) & ridge)
        # edges that separate sectors: open, non-manifold, or sharp curves
        self.cut = (self.uses != 2) | (self.curve & self.sharp)


def reference_normals(normals, n_quads, edges):
    """Unit surface normal under each quad, from the mesh alone (see the
    module doc): its own unit normal plus those of its neighbours across
    smooth edges on no curve."""
    acc = normals.copy()
    keep = ~edges.curve[edges.twice] & ~edges.sharp[edges.twice]
    a, b = edges.e1[keep], edges.e2[keep]
    np.add.at(acc, a, normals[b])
    np.add.at(acc, b, normals[a])
    length = np.linalg.norm(acc, axis=1)
    ref = np.where(length[:, None] > 0, acc / np.where(length > 0, length, 1.0)[:, None], normals)
    return ref[:n_quads]


def scaled_jacobians(xyz, quads, normals):
    """Scaled Jacobian of each quad against its reference normal, and its
    largest corner-angle deviation from 90 degrees."""
    sj = np.full(len(quads), np.inf)
    dev = np.zeros(len(quads))
    p = xyz[quads]
    for i in range(4):
        a = p[:, (i + 1) % 4] - p[:, i]
        b = p[:, (i + 3) % 4] - p[:, i]
        d = np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
        c = np.cross(a, b)
        j = np.where(d > 0, np.einsum("ij,ij->i", c, normals) / np.where(d > 0, d, 1.0), 0.0)
        sj = np.minimum(sj, j)
        ang = np.degrees(np.arctan2(np.linalg.norm(c, axis=1), np.einsum("ij,ij->i", a, b)))
        dev = np.maximum(dev, np.abs(ang - 90.0))
    return sj, dev


class UnionFind:
    """Union-find over arbitrary hashable items."""

    def __init__(self):
        self.parent = {}

    def find(self, x):
        p = self.parent.setdefault(x, x)
        while p != x:
            self.parent[x] = self.parent.setdefault(p, p)
            x, p = p, self.parent[x]
        return x

    def union(self, a, b):
        ra, rb = self.find(a), self.find(b)
        if ra != rb:
            self.parent[ra] = rb


def irregular_boundary(xyz, corners, edges, on_cut):
    """Vertices on a cut edge whose sectors (their corners joined across
    the uncut edges they share) do not hold max(1, round(angle / 90 deg))
    elements each."""
    angles = corner_angles(xyz, corners)
    sel = np.nonzero(on_cut[corners[:, 1]])[0]
    corner_of = {(int(corners[c, 0]), int(corners[c, 1])): int(c) for c in sel}
    uf = UnionFind()
    uncut = edges.twice[~edges.cut[edges.twice]]
    pos = np.nonzero(~edges.cut[edges.twice])[0]
    for k, e1, e2 in zip(uncut, edges.e1[pos], edges.e2[pos]):
        for v in (int(edges.lo[k]), int(edges.hi[k])):
            if on_cut[v]:
                uf.union(corner_of[(int(e1), v)], corner_of[(int(e2), v)])
    sectors = {}
    for c in sel:
        s = sectors.setdefault((int(corners[c, 1]), uf.find(int(c))), [0, 0.0])
        s[0] += 1
        s[1] += float(angles[c])
    return {v for (v, _), (count, angle) in sectors.items() if count != max(1, round(angle / (math.pi / 2)))}


def topology(xyz, corners, n_faces, edges):
    """Valences, interior and corner-aware boundary irregular counts, Euler
    characteristic and the index sum."""
    nv = len(xyz)
    used = np.zeros(nv, dtype=bool)
    used[corners[:, 1]] = True
    valence = np.bincount(np.concatenate([edges.lo, edges.hi]), minlength=nv)
    n_elems = np.bincount(corners[:, 1], minlength=nv)
    mark = lambda sel: np.isin(np.arange(nv), np.concatenate([edges.lo[sel], edges.hi[sel]]))
    on_open, on_cut = mark(edges.uses == 1), mark(edges.cut)
    interior = used & ~on_cut
    irregular_interior = int(np.count_nonzero(interior & (valence != 4)))
    hist = np.bincount(valence[interior]) if interior.any() else np.zeros(0, dtype=np.int64)
    bad = irregular_boundary(xyz, corners, edges, on_cut)
    edge_len = np.linalg.norm(xyz[edges.lo] - xyz[edges.hi], axis=1)
    return {
        "n_vertices": int(np.count_nonzero(used)),
        "n_curve_edges": int(np.count_nonzero(edges.curve)),
        "n_sharp_edges": int(np.count_nonzero(edges.sharp)),
        "euler_characteristic": int(np.count_nonzero(used)) - len(edges.keys) + n_faces,
        "index_sum": int(np.sum(4 - valence[used & ~on_open]) + np.sum(2 - n_elems[on_open])),
        "valence_histogram_interior": {str(v): int(c) for v, c in enumerate(hist) if c},
        "irregular_interior": irregular_interior,
        "irregular_boundary": len(bad),
        "irregular": irregular_interior + len(bad),
        "mean_edge_length": float(edge_len.mean()) if len(edge_len) else None,
    }


def quality(xyz, quads, quad_tags, normals, edges):
    """Scaled Jacobian statistics, Gmsh's SICN and the angle deviation."""
    if len(quads) == 0:
        return {}
    sj, dev = scaled_jacobians(xyz, quads, reference_normals(normals, len(quads), edges))
    sicn = np.asarray(gmsh.model.mesh.getElementQualities(quad_tags.tolist(), "minSICN"))
    return {
        "sj_min": float(sj.min()),
        "sj_mean": float(sj.mean()),
        "sj_p5": float(np.percentile(sj, 5)),
        "sj_frac_ge_0_5": float(np.count_nonzero(sj >= 0.5) / len(sj)),
        "sj_below_0_3": int(np.count_nonzero(sj < 0.3)),
        "inverted_sj": int(np.count_nonzero(sj <= 0)),
        "sicn_min": float(sicn.min()),
        "sicn_mean": float(sicn.mean()),
        "inverted_sicn": int(np.count_nonzero(sicn <= 0)),
        "max_angle_deviation_deg": float(dev.max()),
    }


def metrics(path, sharp_deg):
    """All the numbers of one file."""
    m = load(path)
    out = {
        "file": path,
        "n_nodes": m["n_nodes"],
        "n_quads": int(len(m["quads"])),
        "n_triangles": int(len(m["tris"])),
        "n_other": m["n_other"],
    }
    xyz, quads, tris = m["xyz"], m["quads"], m["tris"]
    corners = corner_table(xyz, quads, tris)
    normals = element_normals(xyz, quads, tris)
    edges = Edges(xyz, corners, normals, element_centroids(xyz, quads, tris), m["curve_edges"], sharp_deg)
    out.update(topology(xyz, corners, len(quads) + len(tris), edges))
    out.update(quality(xyz, quads, m["quad_tags"], normals, edges))
    return out


def main():
    args = sys.argv[1:]
    sharp = 40.0
    if len(args) >= 2 and args[0] == "--sharp-angle":
        sharp = float(args[1])
        args = args[2:]
    if not args:
        print(__doc__, file=sys.stderr)
        return 2
    gmsh.initialize(["gmsh", "-nopopup", "-nt", "1"])
    gmsh.option.setNumber("General.Terminal", 0)
    status = 0
    try:
        for path in args:
            try:
                print(json.dumps(metrics(path, sharp)), flush=True)
            except Exception as e:  # one unreadable file must not hide the others
                print(json.dumps({"file": path, "error": str(e)}), flush=True)
                status = 1
    finally:
        gmsh.finalize()
    return status


if __name__ == "__main__":
    sys.exit(main())
