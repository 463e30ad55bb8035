"""Why the sandbox's lane sweep keeps its data in groups: one contact point's update on one CPU
core, written point by point and eight points at a time, over synthetic rows.

    python benchmarks/lane_layouts.py [--points 4800] [--bodies 1000] [--repeats 200]
                                      [--advanced-optimization off|on]

The Jacobi family's sweep (mass_splitting.sweep_block over per-point blocks) does the same few
dozen multiply-adds on every contact point: two friction rows in a cone, then the soft normal
row with its preload, on copies of the two bodies' velocities, and the weighted changes written
to the block's two slots. This script runs that update on synthetic rows shaped like
``pile_1000``'s (``--points`` points between ``--bodies`` bodies drawn at random) in two forms:

* ``point``: one point per loop item, the rows stored as the sandbox's rows.py stores them (a
  point's vector and matrix components side by side);
* ``lanes``: eight consecutive points per item, every value an 8-vector, each row field stored
  component by component (``ti.Layout.SOA``), so that eight points' values lie side by side.

Both do the same operations in the same order on the same floats (``fast_math`` off, as the
sandbox runs): the script checks that impulses and slots agree bit for bit, then prints
nanoseconds per point update, single-threaded, the best of five runs of ``--repeats`` sweeps.

``--advanced-optimization`` is Taichi's switch for its own IR passes (``ti.init``). With it on,
the ``lanes`` form runs ~3.5x faster than ``point``: LLVM's SLP vectorizer packs eight lanes into
one instruction. The sandbox turns it off (backend.py: it multiplied the solve kernel's compile
time ~10x, measured); off, Taichi reloads the fields' root pointer before every store, LLVM
cannot prove eight lanes' addresses consecutive, and the ``lanes`` form is no faster. That is
why the sandbox keeps the lane sweep's data in fields whose *element* is a group of eight
points (lanes.py), which vectorize with it off: benchmarks/lane_sweep.py times that sweep.
"""

import argparse
import time

import numpy as np
import taichi as ti

LANES = 8


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=4800)
    ap.add_argument("--bodies", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--advanced-optimization", choices=("off", "on"), default="off")
    a = ap.parse_args()
    ti.init(arch=ti.cpu, cpu_max_num_threads=1, fast_math=False, offline_cache=False, log_level=ti.WARN,
            advanced_optimization=a.advanced_optimization == "on")
    n = -(-a.points // LANES) * LANES
    rng = np.random.default_rng(1)
    body_a = rng.integers(0, a.bodies, n).astype(np.int32)
    body_b = ((body_a + 1 + rng.integers(0, a.bodies - 1, n)) % a.bodies).astype(np.int32)
    data = synthetic_rows(rng, n, a.bodies)
    results = {}
    for form, layout in (("point", ti.Layout.AOS), ("lanes", ti.Layout.SOA)):
        f = Fields(n, a.bodies, layout)
        f.fill(body_a, body_b, data)
        sweep = f.sweep_points if form == "point" else f.sweep_lanes
        sweep(1)
        ti.sync()
        results[form] = (f.lam.to_numpy(), f.slot_dv.to_numpy(), f.slot_dw.to_numpy())
        best = float("inf")
        for _ in range(5):
            t = time.perf_counter()
            sweep(a.repeats)
            ti.sync()
            best = min(best, time.perf_counter() - t)
        print(f"{form:6s} {best / a.repeats / n * 1e9:6.1f} ns per point update")
    same = all(np.array_equal(x, y) for x, y in zip(results["point"], results["lanes"]))
    print(f"impulses and slots bit for bit the same: {same}  (advanced_optimization {a.advanced_optimization})")


def synthetic_rows(rng, n: int, bodies: int) -> dict:
    def normal(*shape):
        return rng.standard_normal(shape).astype(np.float32)

    def unit(k):
        v = normal(k, 3)
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    return {
        "lin_a": np.abs(normal(n)) + 0.5, "lin_b": np.abs(normal(n)) + 0.5,
        "ang_a": normal(n, 3, 3), "ang_b": normal(n, 3, 3), "resp_a": normal(n, 3, 3), "resp_b": normal(n, 3, 3),
        "normal": unit(n), "t1": unit(n), "t2": unit(n), "inv_k": np.abs(normal(n, 3)) * 0.1 + 0.1,
        "lam": np.abs(normal(n, 3)), "mu": np.full(n, 0.5, np.float32), "target": normal(n) * 0.1,
        "inv_k_soft": np.abs(normal(n)) * 0.1 + 0.1, "gamma": np.abs(normal(n)) * 0.01,
        "preload": np.abs(normal(n)), "lin_vel": normal(bodies, 3) * 0.01, "ang_vel": normal(bodies, 3) * 0.01,
        "weight": np.full(bodies, 0.25, np.float32),
    }


vec3 = ti.math.vec3
lanes = ti.types.vector(LANES, ti.f32)


@ti.data_oriented
class Fields:
    def __init__(self, n: int, bodies: int, layout):
        def scalar():
            return ti.field(ti.f32, n)

        def vector():
            return ti.Vector.field(3, ti.f32, n, layout=layout)

        def matrix():
            return ti.Matrix.field(3, 3, ti.f32, n, layout=layout)

        self.n = n
        self.body_a, self.body_b = ti.field(ti.i32, n), ti.field(ti.i32, n)
        self.lin_a, self.lin_b, self.mu, self.target = scalar(), scalar(), scalar(), scalar()
        self.inv_k_soft, self.gamma, self.preload = scalar(), scalar(), scalar()
        self.ang_a, self.ang_b, self.resp_a, self.resp_b = matrix(), matrix(), matrix(), matrix()
        self.normal, self.t1, self.t2, self.inv_k, self.lam = vector(), vector(), vector(), vector(), vector()
        self.lin_vel = ti.Vector.field(3, ti.f32, bodies)
        self.ang_vel = ti.Vector.field(3, ti.f32, bodies)
        self.weight = ti.field(ti.f32, bodies)
        self.slot_dv = ti.Vector.field(3, ti.f32, (2, n), layout=layout)  # [side, point]
        self.slot_dw = ti.Vector.field(3, ti.f32, (2, n), layout=layout)

    def fill(self, body_a, body_b, data: dict) -> None:
        self.body_a.from_numpy(body_a)
        self.body_b.from_numpy(body_b)
        for name, values in data.items():
            getattr(self, name).from_numpy(values)

    @ti.func
    def _row(self, m, r: ti.template()):
        return vec3(m[r, 0], m[r, 1], m[r, 2])

    @ti.func
    def point_update(self, q):
        """rows.solve_point (friction, then the soft normal row) and sweep_block's slots, one point."""
        a, b = self.body_a[q], self.body_b[q]
        va0, wa0, vb0, wb0 = self.lin_vel[a], self.ang_vel[a], self.lin_vel[b], self.ang_vel[b]
        va, wa, vb, wb = va0, wa0, vb0, wb0
        ma, mb, ja, jb = self.lin_a[q], self.lin_b[q], self.ang_a[q], self.ang_b[q]
        n, inv_k, lam, ra_, rb_ = self.normal[q], self.inv_k[q], self.lam[q], self.resp_a[q], self.resp_b[q]
        t1, t2 = self.t1[q], self.t2[q]
        dl = vb - va
        f1 = lam[1] - (dl.dot(t1) + wb.dot(self._row(jb, 1)) - wa.dot(self._row(ja, 1))) * inv_k[1]
        f2 = lam[2] - (dl.dot(t2) + wb.dot(self._row(jb, 2)) - wa.dot(self._row(ja, 2))) * inv_k[2]
        limit = self.mu[q] * lam[0]
        mag = ti.sqrt(f1 * f1 + f2 * f2)
        if mag > limit:
            s = limit / mag
            f1 *= s
            f2 *= s
        d1, d2 = f1 - lam[1], f2 - lam[2]
        imp = t1 * d1 + t2 * d2
        va -= ma * imp
        wa -= self._row(ra_, 1) * d1 + self._row(ra_, 2) * d2
        vb += mb * imp
        wb += self._row(rb_, 1) * d1 + self._row(rb_, 2) * d2
        vn = (vb - va).dot(n) + wb.dot(self._row(jb, 0)) - wa.dot(self._row(ja, 0))
        ln = lam[0] - (vn + self.target[q]) * inv_k[0]
        pre = self.preload[q]
        if ln > pre:
            ln = lam[0] - (vn + self.target[q] + self.gamma[q] * (lam[0] - pre)) * self.inv_k_soft[q]
        ln = ti.max(ln, 0.0)
        d = ln - lam[0]
        va -= ma * d * n
        wa -= self._row(ra_, 0) * d
        vb += mb * d * n
        wb += self._row(rb_, 0) * d
        self.lam[q] = vec3(ln, f1, f2)
        wa_, wb_ = self.weight[a], self.weight[b]
        self.slot_dv[0, q] = (va - va0) * wa_
        self.slot_dw[0, q] = (wa - wa0) * wa_
        self.slot_dv[1, q] = (vb - vb0) * wb_
        self.slot_dw[1, q] = (wb - wb0) * wb_

    @ti.func
    def _lanes(self, f: ti.template(), q0, idx: ti.template()):
        v = lanes(0.0)
        for l in ti.static(range(LANES)):
            if ti.static(len(idx) == 0):
                v[l] = f[q0 + l]
            elif ti.static(len(idx) == 1):
                v[l] = f[q0 + l][idx[0]]
            else:
                v[l] = f[q0 + l][idx[0], idx[1]]
        return v

    @ti.func
    def _dot(self, x0, x1, x2, y0, y1, y2):
        return x0 * y0 + x1 * y1 + x2 * y2

    @ti.func
    def lanes_update(self, g):
        """``point_update`` of points 8 g .. 8 g + 7, each value an 8-vector."""
        q0 = g * LANES
        va = [lanes(0.0), lanes(0.0), lanes(0.0)]
        wa = [lanes(0.0), lanes(0.0), lanes(0.0)]
        vb = [lanes(0.0), lanes(0.0), lanes(0.0)]
        wb = [lanes(0.0), lanes(0.0), lanes(0.0)]
        wa_, wb_ = lanes(0.0), lanes(0.0)
        for l in ti.static(range(LANES)):
            a, b = self.body_a[q0 + l], self.body_b[q0 + l]
            wa_[l], wb_[l] = self.weight[a], self.weight[b]
            for e in ti.static(range(3)):
                va[e][l], wa[e][l] = self.lin_vel[a][e], self.ang_vel[a][e]
                vb[e][l], wb[e][l] = self.lin_vel[b][e], self.ang_vel[b][e]
        va0, wa0, vb0, wb0 = [x for x in va], [x for x in wa], [x for x in vb], [x for x in wb]
        ma, mb = self._lanes(self.lin_a, q0, ()), self._lanes(self.lin_b, q0, ())
        n = [self._lanes(self.normal, q0, (e,)) for e in ti.static(range(3))]
        t = [[self._lanes(self.t1, q0, (e,)) for e in ti.static(range(3))],
             [self._lanes(self.t2, q0, (e,)) for e in ti.static(range(3))]]
        inv_k = [self._lanes(self.inv_k, q0, (e,)) for e in ti.static(range(3))]
        lam = [self._lanes(self.lam, q0, (e,)) for e in ti.static(range(3))]
        dl = [vb[e] - va[e] for e in ti.static(range(3))]
        f = [lanes(0.0), lanes(0.0)]
        for r in ti.static(range(2)):
            jb = [self._lanes(self.ang_b, q0, (r + 1, e)) for e in ti.static(range(3))]
            ja = [self._lanes(self.ang_a, q0, (r + 1, e)) for e in ti.static(range(3))]
            f[r] = lam[r + 1] - (self._dot(*dl, *t[r]) + self._dot(*wb, *jb) - self._dot(*wa, *ja)) * inv_k[r + 1]
        limit = self._lanes(self.mu, q0, ()) * lam[0]
        mag = ti.sqrt(f[0] * f[0] + f[1] * f[1])
        scale = limit / mag
        f1 = ti.select(mag > limit, f[0] * scale, f[0])
        f2 = ti.select(mag > limit, f[1] * scale, f[1])
        d1, d2 = f1 - lam[1], f2 - lam[2]
        for e in ti.static(range(3)):
            imp = t[0][e] * d1 + t[1][e] * d2
            va[e] = va[e] - ma * imp
            wa[e] = wa[e] - (self._lanes(self.resp_a, q0, (1, e)) * d1 + self._lanes(self.resp_a, q0, (2, e)) * d2)
            vb[e] = vb[e] + mb * imp
            wb[e] = wb[e] + (self._lanes(self.resp_b, q0, (1, e)) * d1 + self._lanes(self.resp_b, q0, (2, e)) * d2)
        jb0 = [self._lanes(self.ang_b, q0, (0, e)) for e in ti.static(range(3))]
        ja0 = [self._lanes(self.ang_a, q0, (0, e)) for e in ti.static(range(3))]
        vn = self._dot(vb[0] - va[0], vb[1] - va[1], vb[2] - va[2], *n) + self._dot(*wb, *jb0) - self._dot(*wa, *ja0)
        target = self._lanes(self.target, q0, ())
        pre = self._lanes(self.preload, q0, ())
        ln = lam[0] - (vn + target) * inv_k[0]
        soft = lam[0] - (vn + target + self._lanes(self.gamma, q0, ()) * (lam[0] - pre)) \
            * self._lanes(self.inv_k_soft, q0, ())
        ln = ti.max(ti.select(ln > pre, soft, ln), 0.0)
        d = ln - lam[0]
        for e in ti.static(range(3)):
            va[e] = va[e] - ma * d * n[e]
            wa[e] = wa[e] - self._lanes(self.resp_a, q0, (0, e)) * d
            vb[e] = vb[e] + mb * d * n[e]
            wb[e] = wb[e] + self._lanes(self.resp_b, q0, (0, e)) * d
        dva = [(va[e] - va0[e]) * wa_ for e in ti.static(range(3))]
        dwa = [(wa[e] - wa0[e]) * wa_ for e in ti.static(range(3))]
        dvb = [(vb[e] - vb0[e]) * wb_ for e in ti.static(range(3))]
        dwb = [(wb[e] - wb0[e]) * wb_ for e in ti.static(range(3))]
        for l in ti.static(range(LANES)):
            q = q0 + l
            self.lam[q] = vec3(ln[l], f1[l], f2[l])
            self.slot_dv[0, q] = vec3(dva[0][l], dva[1][l], dva[2][l])
            self.slot_dw[0, q] = vec3(dwa[0][l], dwa[1][l], dwa[2][l])
            self.slot_dv[1, q] = vec3(dvb[0][l], dvb[1][l], dvb[2][l])
            self.slot_dw[1, q] = vec3(dwb[0][l], dwb[1][l], dwb[2][l])

    @ti.kernel
    def sweep_points(self, repeats: ti.i32):
        ti.loop_config(serialize=True)
        for _ in range(repeats):
            for q in range(self.n):
                self.point_update(q)

    @ti.kernel
    def sweep_lanes(self, repeats: ti.i32):
        ti.loop_config(serialize=True)
        for _ in range(repeats):
            for g in range(self.n // LANES):
                self.lanes_update(g)


if __name__ == "__main__":
    main()
