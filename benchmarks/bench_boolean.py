"""Benchmark: set operations on closed meshes, ours (manifold3d) against open3d's own.

Robustness: 200 random pairs of closed surfaces (boxes, icospheres, tori,
cylinders, tessellated Bezier ellipsoids) in general and degenerate positions,
25 pairs per category: general overlap, touching faces, coplanar faces, shared
vertices, shared edges, identical meshes, nested solids, near-coincident
copies (half of the degenerate pairs axis-aligned, so the coincidences are
exact; half under a common random rotation, so they hold up to rounding).
Union, intersection and difference of every pair are computed by
``surfaces.boolean`` and by open3d's ``t.geometry.TriangleMesh.boolean_*`` (VTK
based) on the same meshes. open3d runs in a separate worker process that is
restarted when it crashes or exceeds a time limit, which counts as a failure.

A pair succeeds when all three operations return, all three results are
watertight and consistently oriented (closed 2-manifold; an empty result only
where the solids do not overlap), and the volumes satisfy inclusion-exclusion
``vol(A u B) + vol(A n B) = vol(A) + vol(B)`` and ``vol(A - B) = vol(A) -
vol(A n B)`` to 1e-6 relative (volumes by the divergence theorem, float64).

Speed: union of two 100,000-triangle spheres, ours (full call: input checks,
engine, output check, intersection curve) and open3d's, in the same run.

Run: ``.venv/bin/python benchmarks/bench_boolean.py [--pairs 200] [--timeout 30]``.
Writes ``benchmarks/results/boolean.md`` and prints it.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import platform
import time

import numpy as np
from common import Table, write_results
CATEGORIES = (
    "general",
    "touching faces",
    "coplanar faces",
    "shared vertices",
    "shared edges",
    "identical",
    "nested",
    "near-coincident",
)
REL = 1e-6


# ----------------------------------------------------------------------------- shapes
def _box(lo, hi):
    import open3d as o3d

    ext = np.asarray(hi, float) - np.asarray(lo, float)
    m = o3d.geometry.TriangleMesh.create_box(*ext)
    return np.asarray(m.vertices) + np.asarray(lo, float), np.asarray(m.triangles, np.int64)


def _shape(kind: str, rng: np.random.Generator):
    import open3d as o3d

    if kind == "box":
        return _box(np.zeros(3), rng.uniform(0.6, 1.6, 3))
    if kind == "sphere":
        m = o3d.geometry.TriangleMesh.create_sphere(rng.uniform(0.5, 0.9), resolution=16)
    elif kind == "torus":
        m = o3d.geometry.TriangleMesh.create_torus(0.7, rng.uniform(0.2, 0.35), 24, 12)
    elif kind == "cylinder":
        m = o3d.geometry.TriangleMesh.create_cylinder(rng.uniform(0.3, 0.6), 1.5, 24, 2)
    else:
        from surfaces.coons import from_grid
        from surfaces.mesh import tessellate

        th = np.linspace(0, np.pi, 7)
        ph = np.linspace(0, 2 * np.pi, 10, endpoint=False)
        tt, pp = np.meshgrid(th, ph, indexing="ij")
        pts = np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1)
        mesh = tessellate(from_grid(pts * rng.uniform(0.4, 0.9, 3), closed_v=True), samples=3)
        return mesh.vertices, mesh.triangles
    return np.asarray(m.vertices), np.asarray(m.triangles, np.int64)


def _rotation(rng):
    from scipy.spatial.transform import Rotation

    return Rotation.random(random_state=rng).as_matrix()


def _pair(category: str, i: int, rng: np.random.Generator):
    """(va, ta, vb, tb) for pair ``i`` of a category; odd degenerate pairs get a common rotation."""
    kinds = ("box", "sphere", "torus", "cylinder", "ellipsoid")
    common = i % 2 == 1 and category != "general"
    if category == "general":
        va, ta = _shape(kinds[rng.integers(5)], rng)
        vb, tb = _shape(kinds[rng.integers(5)], rng)
        va = (va - va.mean(0)) @ _rotation(rng).T
        vb = (vb - vb.mean(0)) @ _rotation(rng).T + rng.uniform(-0.6, 0.6, 3)
    elif category in ("touching faces", "coplanar faces", "shared edges"):
        hi_a = rng.uniform(0.6, 1.4, 3)
        axis = rng.integers(3)
        lo_b = rng.uniform(0.1, 0.5, 3) * hi_a
        hi_b = lo_b + rng.uniform(0.5, 1.5, 3)
        if category == "touching faces":  # B sits on A's face: shared plane, overlapping patch
            lo_b[axis], hi_b[axis] = hi_a[axis], hi_a[axis] + rng.uniform(0.3, 1.0)
        elif category == "coplanar faces":  # overlapping solids whose top faces are coplanar
            hi_b[axis] = hi_a[axis]
        else:  # B touches A along an edge (diagonal neighbour)
            other = (axis + 1) % 3
            lo_b[axis], hi_b[axis] = hi_a[axis], hi_a[axis] + 0.5
            lo_b[other], hi_b[other] = hi_a[other], hi_a[other] + 0.5
        va, ta = _box(np.zeros(3), hi_a)
        vb, tb = _box(lo_b, hi_b)
    elif category == "shared vertices":
        va, ta = _shape(kinds[rng.integers(5)], rng)
        pivot = va[rng.integers(len(va))]
        vb, tb = (va - pivot) @ _rotation(rng).T + pivot, ta.copy()  # pivot maps onto itself exactly
    elif category == "identical":
        va, ta = _shape(kinds[rng.integers(5)], rng)
        vb, tb = va.copy(), ta.copy()
    elif category == "nested":
        va, ta = _shape(("box", "sphere", "ellipsoid")[rng.integers(3)], rng)
        c = 0.5 * (va.min(0) + va.max(0))
        if i % 4 < 2:  # strictly inside
            vb, tb = (va - c) * rng.uniform(0.3, 0.7) + c, ta.copy()
        else:  # inside, touching A's lowest-x vertex (scaled about it)
            pivot = va[np.argmin(va[:, 0])]
            vb, tb = (va - pivot) * rng.uniform(0.3, 0.7) + pivot, ta.copy()
    else:  # near-coincident: a copy moved by a tiny amount
        va, ta = _shape(kinds[rng.integers(5)], rng)
        vb, tb = va + rng.normal(size=3) * 1e-7, ta.copy()
    if common:
        r, t = _rotation(rng), rng.uniform(-2, 2, 3)
        va, vb = va @ r.T + t, vb @ r.T + t
    return va, ta, vb, tb


# ----------------------------------------------------------------------------- evaluation
def _volume_and_solid(v, t, weld: bool = False):
    """(signed volume, closed and oriented); ``weld`` merges exactly coincident vertices first."""
    from surfaces.mesh import TriangleMesh
    from surfaces.repair import check_solid

    if len(t) == 0:
        return 0.0, True
    v, t = np.asarray(v, float), np.asarray(t, np.int64)
    if weld:
        v, inverse = np.unique(v, axis=0, return_inverse=True)
        t = inverse.ravel()[t]
    info = check_solid(TriangleMesh(v, t), "result")
    return info["signed_volume"], bool(info["closed"] and info["oriented"])


def _judge(va, ta, vb, tb, results):
    """Per-pair verdict from three results {op: (vertices, triangles) or str error}."""
    from surfaces.mesh import signed_volume

    vol_a, vol_b = signed_volume(va, ta), signed_volume(vb, tb)
    out = {"returned": 0, "watertight": 0, "welded": 0, "ok": False, "errors": []}
    vols = {}
    for op, res in results.items():
        if isinstance(res, str):
            out["errors"].append(res)
            continue
        out["returned"] += 1
        vol, solid = _volume_and_solid(*res)
        out["watertight"] += int(solid)
        if not solid:
            vol, solid = _volume_and_solid(*res, weld=True)
        out["welded"] += int(solid)
        vols[op] = vol
    if len(vols) == 3 and out["welded"] == 3:
        scale = vol_a + vol_b
        ident1 = abs(vols["union"] + vols["intersection"] - scale) <= REL * scale
        ident2 = abs(vols["difference"] - (vol_a - vols["intersection"])) <= REL * scale
        out["ok"] = bool(ident1 and ident2)
    out["volumes"] = vols
    return out


def _ours(va, ta, vb, tb):
    from surfaces.boolean import OPS, boolean
    from surfaces.mesh import TriangleMesh

    a, b = TriangleMesh(va, ta), TriangleMesh(vb, tb)
    results = {}
    for op in OPS:
        try:
            r = boolean(a, b, op)
            results[op] = (r.mesh.vertices, r.mesh.triangles)
        except Exception as exc:  # noqa: BLE001 - every failure is counted, whatever its type
            results[op] = f"{type(exc).__name__}: {exc}"
    return results


def _open3d_worker(conn) -> None:
    """Runs open3d booleans for the parent; may die on a crash (the parent restarts it)."""
    import open3d as o3d

    core = o3d.core
    while True:
        msg = conn.recv()
        if msg is None:
            return
        op, va, ta, vb, tb = msg
        try:
            a = o3d.t.geometry.TriangleMesh()
            a.vertex.positions = core.Tensor(np.ascontiguousarray(va, np.float64))
            a.triangle.indices = core.Tensor(np.ascontiguousarray(ta, np.int64))
            b = o3d.t.geometry.TriangleMesh()
            b.vertex.positions = core.Tensor(np.ascontiguousarray(vb, np.float64))
            b.triangle.indices = core.Tensor(np.ascontiguousarray(tb, np.int64))
            t0 = time.perf_counter()
            r = getattr(a, f"boolean_{op}")(b)
            dt = time.perf_counter() - t0
            v = r.vertex.positions.numpy().astype(np.float64) if "positions" in r.vertex else np.zeros((0, 3))
            t = r.triangle.indices.numpy().astype(np.int64) if "indices" in r.triangle else np.zeros((0, 3), np.int64)
            conn.send((v, t, dt))
        except Exception as exc:  # noqa: BLE001 - reported to the parent as a failure
            conn.send(f"{type(exc).__name__}: {exc}")


class Open3DPool:
    """One guarded open3d worker process; crashed or hung workers are replaced."""

    def __init__(self, timeout: float) -> None:
        self.timeout = timeout
        self.ctx = mp.get_context("spawn")
        self.proc = None
        self.crashes = 0
        self.timeouts = 0
        self._start()

    def _start(self) -> None:
        self.conn, child = self.ctx.Pipe()
        self.proc = self.ctx.Process(target=_open3d_worker, args=(child,), daemon=True)
        self.proc.start()

    def _restart(self) -> None:
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join()
        self._start()

    def run(self, op, va, ta, vb, tb, timeout: float | None = None):
        """(vertices, triangles, seconds) or an error string."""
        timeout = self.timeout if timeout is None else timeout
        try:
            self.conn.send((op, va, ta, vb, tb))
            if not self.conn.poll(timeout):
                self.timeouts += 1
                self._restart()
                return f"timeout > {timeout:g} s"
            return self.conn.recv()
        except (EOFError, BrokenPipeError, ConnectionResetError):
            self.crashes += 1
            self.proc.join(5)
            code = self.proc.exitcode
            self._restart()
            return f"worker crashed (exit code {code})"

    def close(self) -> None:
        try:
            self.conn.send(None)
        except (BrokenPipeError, OSError):
            pass
        self.proc.join(5)
        if self.proc.is_alive():
            self.proc.kill()


def _open3d(pool: Open3DPool, va, ta, vb, tb):
    results = {}
    for op in ("union", "intersection", "difference"):
        r = pool.run(op, va, ta, vb, tb)
        results[op] = r if isinstance(r, str) else (r[0], r[1])
    return results


def _sphere(n_tri: int, centre):
    import open3d as o3d

    res = int(round(np.sqrt(n_tri / 4)))
    m = o3d.geometry.TriangleMesh.create_sphere(1.0, resolution=res)
    return np.asarray(m.vertices) + centre, np.asarray(m.triangles, np.int64)


def _precision_rows() -> list[list[str]]:
    """Identity residual through manifold3d's float32 Mesh (raw coordinates) vs our Mesh64 path."""
    import manifold3d

    from surfaces.boolean import OPS, boolean
    from surfaces.mesh import TriangleMesh, signed_volume

    rows = []
    for label, centre in (
        ("near the origin", np.zeros(3)),
        ("CT coordinates (~500 mm)", np.array([480.0, -310.0, 1250.0])),
    ):
        va, ta = _sphere(20_000, centre)
        vb, tb = _sphere(20_000, centre + [0.6, 0.2, 0.1])
        va, vb = va * 10 - centre * 9, vb * 10 - centre * 9  # radius 10 mm
        ref = signed_volume(va, ta) + signed_volume(vb, tb)
        r = {op: boolean(TriangleMesh(va, ta), TriangleMesh(vb, tb), op).volume for op in OPS}
        ours = abs(r["union"] + r["intersection"] - ref) / ref
        ma = manifold3d.Manifold(manifold3d.Mesh(vert_properties=va.astype(np.float32), tri_verts=ta.astype(np.uint32)))
        mb = manifold3d.Manifold(manifold3d.Mesh(vert_properties=vb.astype(np.float32), tri_verts=tb.astype(np.uint32)))
        vol32 = []
        for s in (ma + mb, ma ^ mb):
            m = s.to_mesh()
            vol32.append(
                signed_volume(np.asarray(m.vert_properties, np.float64)[:, :3], np.asarray(m.tri_verts, np.int64))
            )
        f32 = abs(sum(vol32) - ref) / ref
        rows.append([label, f"{ours:.1e}", f"{f32:.1e}"])
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=200, help="number of random pairs (spread over 8 categories)")
    parser.add_argument("--timeout", type=float, default=30.0, help="open3d time limit per operation [s]")
    parser.add_argument("--speed-triangles", type=int, default=100_000, help="triangles per mesh in the speed test")
    parser.add_argument("--seed", type=int, default=0, help="random seed")
    parser.add_argument("--speed-timeout", type=float, default=300.0, help="open3d time limit in the speed test [s]")
    args = parser.parse_args()
    from tqdm import tqdm

    from surfaces.boolean import union

    rng = np.random.default_rng(args.seed)
    per_cat = {c: {"ours": [], "open3d": []} for c in CATEGORIES}
    pool = Open3DPool(args.timeout)
    errors: dict[str, int] = {}
    t_ours = t_o3d = 0.0
    try:
        for k in tqdm(range(args.pairs), desc="pairs", unit="pair"):
            cat = CATEGORIES[k % len(CATEGORIES)]
            va, ta, vb, tb = _pair(cat, k // len(CATEGORIES), rng)
            t0 = time.perf_counter()
            ours = _judge(va, ta, vb, tb, _ours(va, ta, vb, tb))
            t1 = time.perf_counter()
            theirs = _judge(va, ta, vb, tb, _open3d(pool, va, ta, vb, tb))
            t2 = time.perf_counter()
            t_ours, t_o3d = t_ours + t1 - t0, t_o3d + t2 - t1
            per_cat[cat]["ours"].append(ours)
            per_cat[cat]["open3d"].append(theirs)
            for err in theirs["errors"]:
                key = err.split(":")[0][:60]
                errors[key] = errors.get(key, 0) + 1

        # speed: union of two n-triangle spheres
        va, ta = _sphere(args.speed_triangles, np.zeros(3))
        vb, tb = _sphere(args.speed_triangles, np.array([0.5, 0.3, 0.2]))
        from surfaces.mesh import TriangleMesh

        a, b = TriangleMesh(va, ta), TriangleMesh(vb, tb)
        import manifold3d

        times, cpu, engine, engine_cpu = [], [], [], []
        for _ in range(5):
            t0, c0 = time.perf_counter(), time.process_time()
            res = union(a, b)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
            t0, c0 = time.perf_counter(), time.process_time()
            ma = manifold3d.Manifold(manifold3d.Mesh64(vert_properties=va, tri_verts=ta.astype(np.uint64)))
            mb = manifold3d.Manifold(manifold3d.Mesh64(vert_properties=vb, tri_verts=tb.astype(np.uint64)))
            (ma + mb).to_mesh64()
            engine.append(time.perf_counter() - t0)
            engine_cpu.append(time.process_time() - c0)
        load = os.getloadavg()[0]
        ours_speed, ours_cpu, engine_speed = min(times), min(cpu), min(engine)
        o3d_res = pool.run("union", va, ta, vb, tb, timeout=args.speed_timeout)
        speed_timeout = isinstance(o3d_res, str)
        o3d_speed = np.nan if speed_timeout else o3d_res[2]
        o3d_solid = (
            (False, False) if speed_timeout else tuple(_volume_and_solid(*o3d_res[:2], weld=w)[1] for w in (0, 1))
        )
    finally:
        pool.close()
    precision = _precision_rows()

    def rate(rows, key):
        if key == "ok":
            return sum(r["ok"] for r in rows), len(rows)
        return sum(r[key] for r in rows), 3 * len(rows)

    columns = {"ours": ("returned", "watertight", "ok"), "open3d": ("returned", "watertight", "welded", "ok")}
    tot = {lib: {key: [0, 0] for key in keys} for lib, keys in columns.items()}
    robustness = []
    for cat in CATEGORIES:
        cells = []
        for lib, keys in columns.items():
            for key in keys:
                n, d = rate(per_cat[cat][lib], key)
                tot[lib][key][0] += n
                tot[lib][key][1] += d
                cells.append(f"{n}/{d}")
        robustness.append([cat, len(per_cat[cat]["ours"]), *cells])
    cells = []
    for lib, keys in columns.items():
        for key in keys:
            n, d = tot[lib][key]
            cells.append(f"**{n}/{d} ({100 * n / max(d, 1):.0f} %)**")
    robustness.append(["all", args.pairs, *cells])
    totals = (
        f"Total time for all pairs: ours {t_ours:.2f} s, open3d {t_o3d:.2f} s "
        f"(ratio {t_o3d / max(t_ours, 1e-9):.0f}x). open3d worker crashes (segmentation faults): "
        f"{pool.crashes}, timeouts: {pool.timeouts}."
    )
    if errors:
        totals += (
            "\nopen3d failed operations by kind: " + ", ".join(f"{k} ({v})" for k, v in sorted(errors.items())) + "."
        )
    o3d_row = (
        ["open3d `boolean_union`", f"> {args.speed_timeout:g} (timeout)", "-", "-", "-",
         f"> {args.speed_timeout / ours_speed:.0f}x"]
        if speed_timeout
        else ["open3d `boolean_union`", f"{o3d_speed:.3f}", "-", f"{len(o3d_res[1]):,}",
              f"{o3d_solid[0]} / {o3d_solid[1]}", f"{o3d_speed / ours_speed:.1f}x"]
    )
    text = write_results("boolean", "Set operations (`surfaces.boolean`, manifold3d) vs open3d boolean_*", [
        f"Command: `.venv/bin/python benchmarks/bench_boolean.py --pairs {args.pairs} --timeout {args.timeout:g}` "
        f"(seed {args.seed}; {platform.machine()}, {os.cpu_count()} cores shared with other work).",
        f"Robustness: {args.pairs} random pairs, union + intersection + difference each. "
        "*returned*: operations that gave a mesh (open3d: no exception, crash or timeout); "
        "*watertight*: results that are closed and consistently oriented as returned; "
        "*welded*: watertight as returned or after merging exactly coincident vertices (open3d "
        "duplicates the vertices along the intersection curve); *pairs ok*: all three results watertight "
        "(welded) and inclusion-exclusion of the volumes holds to 1e-6 relative.",
        Table(
            ["category", "pairs", "ours returned", "ours watertight", "ours pairs ok", "open3d returned",
             "open3d watertight", "open3d welded", "open3d pairs ok"],
            robustness,
            align="lrrrrrrrr",
        ),
        totals,
        f"Speed: union of two {len(ta):,}-triangle spheres (radius 1, offset 0.62), best of 5. "
        f"The machine's load average was {load:.1f} on {os.cpu_count()} cores during the timing, "
        "so wall times are inflated; the CPU time of our process is given too.",
        Table(
            ["", "wall s", "CPU s", "result triangles", "watertight (as returned / welded)", "ratio (wall)"],
            [
                ["ours (`surfaces.boolean.union`: input checks, manifold3d, output check, curve)",
                 f"{ours_speed:.3f}", f"{ours_cpu:.3f}", f"{len(res.mesh.triangles):,}",
                 res.summary()["watertight"], "1"],
                ["manifold3d alone (Mesh64 in, union, Mesh64 out)", f"{engine_speed:.3f}", f"{min(engine_cpu):.3f}",
                 "-", "-", f"{engine_speed / ours_speed:.2f}x"],
                o3d_row,
            ],
            align="lrrrrr",
        ),
        "Precision: relative residual of vol(A u B) + vol(A n B) - vol(A) - vol(B) for two 10 mm "
        "spheres (20,000 triangles each), through our float64 path (Mesh64, centred) and "
        "through manifold3d's float32 `Mesh` with the raw coordinates.",
        Table(["position", "ours (float64, centred)", "float32 Mesh, raw coordinates"], precision, align="lrr"),
    ])
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
