#!/usr/bin/env python3
"""Gmsh reference timings for the meshatlas bench (issue 2 §7, issue 13).

Usage: python3 benches/gmsh_reference.py FILE [STAGES] [OUT_DIR]

STAGES is a comma-separated subset of atlas,crossfield,quads (default:
atlas,crossfield). OUT_DIR (default: a temporary directory) receives the
files that are kept: `gmsh_quads.msh` for the quads stage.
Prints one JSON object per line on stdout as soon as each step is timed
(only the Gmsh call is timed), so the steps before a crash or a kill are kept:
  {"step": "load", "seconds": s}        gmsh.merge(FILE)
  {"step": "atlas", "seconds": s}       classifySurfaces(40 deg, True, True, pi) + createGeometry()
  {"step": "atlas.write", "seconds": s} gmsh.write() of the atlas as MSH 4.1 with its
                                        parametrizations (Mesh.SaveParametric), like atlas.msh
  {"step": "crossfield", "seconds": s}  computeCrossField() on the classified geometry
  {"mesh_size": h}                      quads: the target size, the mean input edge length
                                        (meshatlas's default `quads.size`)
  {"step": "quads", "seconds": s}       quads: generate(2) with the quasi-structured quad
                                        mesher (Mesh.Algorithm 11, RecombineAll 1, 1 thread)
  {"step": "quads.write", "seconds": s} quads: gmsh.write(OUT_DIR/gmsh_quads.msh), MSH 4.1
  {"n_triangles": n, "peak_rss_kb": k}  at the end (ru_maxrss, kB on Linux)

The quads stage runs on the atlas of this script (classifySurfaces +
createGeometry), not on meshatlas's. It uses 1 thread because with 2 the
quasi-structured mesher deadlocks (Gmsh 4.15.2); on some inputs it never
finishes even with 1, so the caller enforces a time limit by killing this
process (the bench's `--gmsh-timeout`).

Known: with the gmsh 4.15.2 wheel, computeCrossField() segfaults after its
smoothing iterations on the meshes tried here (disk, sphere); the bench
reports the crash and keeps the earlier steps.
"""
import json
import math
import resource
import os
import sys
import tempfile
import time

import gmsh


def emit(obj):
    print(json.dumps(obj), flush=True)


def timed(name, fn):
    t = time.perf_counter()
    fn()
    emit({"step": name, "seconds": time.perf_counter() - t})


def atlas():
    gmsh.model.mesh.classifySurfaces(40 * math.pi / 180, True, True, math.pi)
    gmsh.model.mesh.createGeometry()


def mean_edge_length():
    """Mean length of the input triangles' edges, each triangle counting its
    three (the definition of meshatlas's `TriMesh::mean_edge_length`)."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    xyz = {int(t): coords[3 * i : 3 * i + 3] for i, t in enumerate(tags)}
    total, count = 0.0, 0
    for etype, _, nodes in zip(*gmsh.model.mesh.getElements(2)):
        k = gmsh.model.mesh.getElementProperties(etype)[5]
        for e in range(len(nodes) // k):
            corner = [xyz[int(n)] for n in nodes[e * k : e * k + 3]]
            for i in range(3):
                a, b = corner[i], corner[(i + 1) % 3]
                total += math.dist(a, b)
                count += 1
    return total / count if count else 0.0


def quads(out_dir, h):
    """Gmsh's quasi-structured quad mesh at size `h` (the mean input edge
    length, measured on the input before the atlas)."""
    emit({"mesh_size": h})
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.option.setNumber("Mesh.Algorithm", 11)
    gmsh.option.setNumber("Mesh.RecombineAll", 1)
    gmsh.option.setNumber("Mesh.MeshSizeMin", h)
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    timed("quads", lambda: gmsh.model.mesh.generate(2))
    gmsh.option.setNumber("Mesh.SaveParametric", 0)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    timed("quads.write", lambda: gmsh.write(os.path.join(out_dir, "gmsh_quads.msh")))


def main():
    if len(sys.argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    path = sys.argv[1]
    stages = sys.argv[2].split(",") if len(sys.argv) > 2 and sys.argv[2] else ["atlas", "crossfield"]
    out_dir = sys.argv[3] if len(sys.argv) > 3 else None
    gmsh.initialize(["gmsh", "-nopopup", "-nt", "1"])
    try:
        with tempfile.TemporaryDirectory() as tmp:
            out_dir = out_dir or tmp
            os.makedirs(out_dir, exist_ok=True)
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.option.setNumber("General.NumThreads", 1)
            timed("load", lambda: gmsh.merge(path))
            _, tags, _ = gmsh.model.mesh.getElements(2)
            n_triangles = sum(len(t) for t in tags)
            h = mean_edge_length() if "quads" in stages else None
            if any(s in stages for s in ("atlas", "crossfield", "quads")):
                timed("atlas", atlas)
                gmsh.option.setNumber("Mesh.SaveParametric", 1)
                timed("atlas.write", lambda: gmsh.write(os.path.join(tmp, "atlas.msh")))
            if "crossfield" in stages:
                timed("crossfield", gmsh.model.mesh.computeCrossField)
            if "quads" in stages:
                quads(out_dir, h)
    finally:
        gmsh.finalize()
    emit({"n_triangles": n_triangles, "peak_rss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss})
    return 0


if __name__ == "__main__":
    sys.exit(main())
