#!/usr/bin/env python3
"""Gmsh reference timings for the meshatlas bench (issue 2 §7).

Usage: python3 benches/gmsh_reference.py FILE [STAGES]

STAGES is a comma-separated subset of atlas,crossfield (default: both).
Prints one JSON object per line on stdout as soon as each step is timed
(only the Gmsh call is timed), so the steps before a crash are kept:
  {"step": "load", "seconds": s}        gmsh.merge(FILE)
  {"step": "atlas", "seconds": s}       classifySurfaces(40 deg, True, True, pi) + createGeometry()
  {"step": "atlas.write", "seconds": s} gmsh.write() of the atlas as MSH 4.1 with its
                                        parametrizations (Mesh.SaveParametric), like atlas.msh
  {"step": "crossfield", "seconds": s}  computeCrossField() on the classified geometry
  {"n_triangles": n, "peak_rss_kb": k}  at the end (ru_maxrss, kB on Linux)

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


def main():
    if len(sys.argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    path = sys.argv[1]
    stages = sys.argv[2].split(",") if len(sys.argv) > 2 and sys.argv[2] else ["atlas", "crossfield"]
    gmsh.initialize(["gmsh", "-nopopup"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        timed("load", lambda: gmsh.merge(path))
        _, tags, _ = gmsh.model.mesh.getElements(2)
        n_triangles = sum(len(t) for t in tags)
        if "atlas" in stages or "crossfield" in stages:
            timed("atlas", atlas)
            with tempfile.TemporaryDirectory() as tmp:
                gmsh.option.setNumber("Mesh.SaveParametric", 1)
                timed("atlas.write", lambda: gmsh.write(os.path.join(tmp, "atlas.msh")))
        if "crossfield" in stages:
            timed("crossfield", gmsh.model.mesh.computeCrossField)
    finally:
        gmsh.finalize()
    emit({"n_triangles": n_triangles, "peak_rss_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss})
    return 0


if __name__ == "__main__":
    sys.exit(main())
