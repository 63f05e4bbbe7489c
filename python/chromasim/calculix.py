"""An independent reference for the dome's mechanics: CalculiX (Debian `calculix-ccx`) on a
gmsh mesh (Debian `gmsh`) of the same layered dome, pressed by a rigid flat or sphere.

- Geometry: the four conformal layers between spheres of radius 10.5, 11.0, 12.2, 12.7 and
  13.2 mm (z >= 0), meshed by gmsh's OpenCASCADE kernel into curved quadratic tets (C3D10),
  `h` mm near the apex growing to 2 h at the rim. The rim plane z = 0 is clamped.
- A press is axisymmetric, frictionless or with Coulomb friction (`mu` > 0: *FRICTION with a
  stick slope), so a 30 deg sector is solved (sideways motion fixed on its phi = 0 face, zero
  normal motion on its other face by *EQUATION, the axis fixed sideways) and the force scaled
  by 360 / 30. A quarter model agrees within 0.1 % (frictionless).
- Materials: small strain (*ELASTIC) or NLGEOM with *HYPERELASTIC, NEO HOOKE, C10 = mu / 2,
  D1 = 2 / kappa, from each layer's E and nu as chromasim's neo-Hookean model takes them.
- The indenter is a slab of C3D8 whose bottom face is the plane or the sphere; every slab
  node is driven down by a displacement ramp (so it is rigid), surface-to-surface penalty
  contact (50 MPa/mm). The force is read off the converged increments: a force-controlled
  step leaves the indenter singular whenever contact opens.
- Contact area: the part of the deformed outer surface that the indenter overlaps (penalty
  contact: a closed gap is a small overclosure), sampled on each curved 6-node face.
"""

import dataclasses
import math
import os
import pathlib
import subprocess
import time

import numpy as np

RADII_MM = (10.5, 11.0, 12.2, 12.7, 13.2)
MATERIALS = ((0.8, 0.45), (0.3, 0.45), (0.8, 0.45), (1.0, 0.45))  # (E MPa, nu), innermost first
R_OUT = RADII_MM[-1]


@dataclasses.dataclass
class Case:
    object: str = "flat"           # flat | sphere
    model: str = "neohooke"        # linear | neohooke
    h_mm: float = 0.5              # element size near the apex (2 h at the rim)
    sphere_radius_mm: float = 45.0
    max_indentation_mm: float = 3.4
    wedge_deg: float = 30.0
    penalty_MPa_per_mm: float = 50.0
    mu: float = 0.0                # Coulomb friction (0: frictionless)
    stick_slope_MPa_per_mm: float = 500.0
    slab_half_mm: float = 15.0
    slab_cells: int = 30           # per side of the slab
    max_step: float = 0.05         # of the ramp, per increment
    threads: int = 2

    def name(self):
        friction = f"_mu{self.mu:g}" if self.mu else ""
        return f"{self.object}_{self.model}_h{self.h_mm:g}{friction}"


GEO = """SetFactory("OpenCASCADE");
R[] = {{{radii}}};
For i In {{0:4}}
  Sphere(i+1) = {{0,0,0,R[i],0,Pi/2,{phi}}};
EndFor
BooleanDifference(14) = {{ Volume{{5}}; Delete; }}{{ Volume{{4}}; }};
BooleanDifference(13) = {{ Volume{{4}}; Delete; }}{{ Volume{{3}}; }};
BooleanDifference(12) = {{ Volume{{3}}; Delete; }}{{ Volume{{2}}; }};
BooleanDifference(11) = {{ Volume{{2}}; Delete; }}{{ Volume{{1}}; Delete; }};
v[] = BooleanFragments{{ Volume{{11,12,13,14}}; Delete; }}{{}};
Physical Volume(1) = {{Volume{{:}}}};
pa[] = Point In BoundingBox{{-1e-4,-1e-4,{rout}-1e-4, 1e-4,1e-4,{rout}+1e-4}};
Field[1] = Distance;
Field[1].PointsList = {{pa[0]}};
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = {h};
Field[2].SizeMax = {hfar};
Field[2].DistMin = 10;
Field[2].DistMax = 16;
Background Field = 2;
Mesh.MeshSizeExtendFromBoundary = 0;
Mesh.MeshSizeFromPoints = 0;
Mesh.MeshSizeFromCurvature = 0;
Mesh.ElementOrder = 2;
Mesh.SecondOrderLinear = 0;
"""


def build_mesh(case, wd):
    """gmsh's curved C3D10 mesh of the sector: node ids, positions (n x 3), tets (m x 10) in
    CalculiX's node order."""
    geo, msh = wd / "dome.geo", wd / "dome.msh"
    geo.write_text(GEO.format(radii=", ".join(f"{r:g}" for r in RADII_MM),
                              phi=f"{math.radians(case.wedge_deg):.12g}", rout=R_OUT,
                              h=case.h_mm, hfar=2 * case.h_mm))
    run = subprocess.run(["gmsh", str(geo), "-3", "-format", "msh22", "-o", str(msh)],
                         capture_output=True, text=True, check=False)
    (wd / "gmsh.log").write_text(run.stdout + run.stderr)
    if run.returncode != 0 or not msh.exists():
        raise RuntimeError(f"gmsh failed: see {wd / 'gmsh.log'}")
    return read_msh22(msh)


def read_msh22(path):
    nodes, tets = {}, []
    lines = iter(pathlib.Path(path).read_text().splitlines())
    for line in lines:
        if line == "$Nodes":
            for _ in range(int(next(lines))):
                p = next(lines).split()
                nodes[int(p[0])] = (float(p[1]), float(p[2]), float(p[3]))
        elif line == "$Elements":
            for _ in range(int(next(lines))):
                p = list(map(int, next(lines).split()))
                if p[1] == 11:  # 10-node tet; gmsh's last two edge nodes are CalculiX's swapped
                    conn = p[3 + p[2]:]
                    tets.append(conn[:8] + [conn[9], conn[8]])
    ids = np.array(sorted(nodes))
    return ids, np.array([nodes[i] for i in ids]), np.array(tets, dtype=np.int64)


def indenter_bottom(case, x, y):
    """Height of the indenter's bottom face at rest (touching the apex) over (x, y)."""
    if case.object == "flat":
        return R_OUT + 0.0 * x
    R = case.sphere_radius_mm
    return R_OUT + R - np.sqrt(R * R - x * x - y * y)


def slab(case, first_node, first_element):
    """The indenter: a slab of C3D8 over the sector, its bottom face the object's surface
    touching the apex. Returns {node: xyz}, {element: 8 nodes} (face S1 is the bottom)."""
    xs = np.linspace(0.0, case.slab_half_mm, case.slab_cells + 1)

    nodes, index = {}, {}
    nid = first_node
    for i, x in enumerate(xs):
        for j, y in enumerate(xs):
            for k in (0, 1):
                nid += 1
                index[(i, j, k)] = nid
                nodes[nid] = (x, y, indenter_bottom(case, x, y) + k)
    elements, eid = {}, first_element
    for i in range(len(xs) - 1):
        for j in range(len(xs) - 1):
            eid += 1
            quad = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
            elements[eid] = [index[(a, b, 0)] for a, b in quad] + [index[(a, b, 1)] for a, b in quad]
    return nodes, elements


FACES = {1: (0, 1, 2), 2: (0, 3, 1), 3: (1, 3, 2), 4: (2, 3, 0)}  # C3D10 faces, corner nodes
FACE_EDGES = {1: (4, 5, 6), 2: (7, 8, 4), 3: (8, 9, 5), 4: (9, 7, 6)}  # their edge nodes ab bc ca


def outer_faces(X, rows):
    """(element row, face) of the boundary faces on the outer sphere above z = 3 mm."""
    seen = {}
    for e in range(len(rows)):
        for face, corners in FACES.items():
            seen.setdefault(tuple(sorted(rows[e, list(corners)])), []).append((e, face))
    out = []
    for key, owners in seen.items():
        p = X[list(key)]
        if len(owners) == 1 and np.all(np.abs(np.linalg.norm(p, axis=1) - R_OUT) < 1e-3) \
                and p[:, 2].mean() > 3.0:
            out.append(owners[0])
    return out


def _lines(values, per=8):
    return "".join(", ".join(str(v) for v in values[i:i + per]) + "\n"
                   for i in range(0, len(values), per))


def write_deck(case, wd, ids, X, tets):
    """job.inp; returns the tets as row indices into X."""
    row_of = {int(n): i for i, n in enumerate(ids)}
    rows = np.vectorize(row_of.get)(tets)
    layer = np.searchsorted(np.array(RADII_MM[1:-1]), np.linalg.norm(X[rows[:, :4]].mean(1), axis=1))
    eids = np.arange(1, len(tets) + 1)
    th = math.radians(case.wedge_deg)
    axis = np.hypot(X[:, 0], X[:, 1]) < 1e-6
    rim = np.abs(X[:, 2]) < 1e-6
    phi0 = (np.abs(X[:, 1]) < 1e-6) & ~axis
    phi1 = (np.abs(X @ np.array([-math.sin(th), math.cos(th), 0.0])) < 1e-6) & ~axis & ~rim
    ind_nodes, ind_elems = slab(case, int(ids.max()), len(tets))
    d = []
    d.append(f"*HEADING\nchromasim cross-check {case.name()}\n*NODE, NSET=NALL\n")
    d += [f"{n}, {p[0]:.9g}, {p[1]:.9g}, {p[2]:.9g}\n" for n, p in zip(ids, X)]
    d += [f"{n}, {p[0]:.9g}, {p[1]:.9g}, {p[2]:.9g}\n" for n, p in ind_nodes.items()]
    for L in range(4):
        d.append(f"*ELEMENT, TYPE=C3D10, ELSET=LAYER{L + 1}\n")
        d += [f"{eids[e]}, " + ", ".join(map(str, tets[e])) + "\n" for e in np.where(layer == L)[0]]
    d.append("*ELEMENT, TYPE=C3D8, ELSET=EIND\n")
    d += [f"{e}, " + ", ".join(map(str, c)) + "\n" for e, c in ind_elems.items()]
    for name, mask in (("RIM", rim), ("AXIS", axis), ("PHI0", phi0)):
        d.append(f"*NSET, NSET={name}\n" + _lines([int(v) for v in ids[mask]]))
    d.append("*NSET, NSET=IND\n" + _lines(sorted(ind_nodes)))
    for L, (E, nu) in enumerate(MATERIALS):
        d.append(f"*MATERIAL, NAME=M{L + 1}\n")
        if case.model == "linear":
            d.append(f"*ELASTIC\n{E:.9g}, {nu:.9g}\n")
        else:
            mu, kappa = E / (2 * (1 + nu)), E / (3 * (1 - 2 * nu))
            d.append(f"*HYPERELASTIC, NEO HOOKE\n{mu / 2:.9g}, {2 / kappa:.9g}\n")
        d.append(f"*SOLID SECTION, ELSET=LAYER{L + 1}, MATERIAL=M{L + 1}\n")
    d.append("*MATERIAL, NAME=MIND\n*ELASTIC\n1000., 0.3\n*SOLID SECTION, ELSET=EIND, MATERIAL=MIND\n")
    d.append("*SURFACE, NAME=SDOME, TYPE=ELEMENT\n")
    d += [f"{eids[e]}, S{face}\n" for e, face in outer_faces(X, rows)]
    d.append("*SURFACE, NAME=SIND, TYPE=ELEMENT\n" + "".join(f"{e}, S1\n" for e in ind_elems))
    d.append("*CONTACT PAIR, INTERACTION=SI1, TYPE=SURFACE TO SURFACE\nSDOME, SIND\n"
             "*SURFACE INTERACTION, NAME=SI1\n*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR\n"
             f"{case.penalty_MPa_per_mm:g}\n"
             + (f"*FRICTION\n{case.mu:g}, {case.stick_slope_MPa_per_mm:g}\n" if case.mu else ""))
    d.append("*BOUNDARY\nRIM, 1, 3\nIND, 1, 2\nAXIS, 1, 2\nPHI0, 2, 2\n*EQUATION\n")
    d += [f"2\n{n}, 2, {math.cos(th):.12g}, {n}, 1, {-math.sin(th):.12g}\n" for n in ids[phi1]]
    nlgeom = ", NLGEOM" if case.model == "neohooke" else ""
    d.append(f"*STEP{nlgeom}, INC=1000\n*STATIC\n0.02, 1.0, 1e-05, {case.max_step:g}\n"
             f"*BOUNDARY\nIND, 3, 3, {-case.max_indentation_mm:.9g}\n"
             "*NODE PRINT, NSET=IND, TOTALS=ONLY\nRF\n*NODE FILE, NSET=NALL\nU\n*END STEP\n")
    (wd / "job.inp").write_text("".join(d))
    return rows


def read_forces(dat):
    """{increment time: total force (N) on the slab along -z, in the sector}."""
    out = {}
    lines = pathlib.Path(dat).read_text().splitlines()
    for i, line in enumerate(lines):
        if "total force" in line and "for set IND" in line:
            j = i + 1
            while not lines[j].strip():
                j += 1
            out[float(line.split()[-1])] = -float(lines[j].split()[2])
    return out


def read_displacements(frd):
    """[(increment time, {node: (ux, uy, uz)})] from job.frd."""
    res, t = [], None
    with open(frd) as f:
        it = iter(f)
        for line in it:
            if line.startswith("  100C"):
                t = float(line[12:24])
            elif line.startswith(" -4  DISP"):
                u = {}
                for l2 in it:
                    if l2.startswith(" -3"):
                        break
                    if l2.startswith(" -1"):
                        u[int(l2[3:13])] = (float(l2[13:25]), float(l2[25:37]), float(l2[37:49]))
                res.append((t, u))
    return res


def shape10(L):
    L1, L2, L3, L4 = L
    return np.array([L1 * (2 * L1 - 1), L2 * (2 * L2 - 1), L3 * (2 * L3 - 1), L4 * (2 * L4 - 1),
                     4 * L1 * L2, 4 * L2 * L3, 4 * L3 * L1, 4 * L1 * L4, 4 * L2 * L4, 4 * L3 * L4])


def dshape10(L):
    D = np.zeros((10, 4))
    for i in range(4):
        D[i, i] = 4 * L[i] - 1
    for k, (i, j) in enumerate([(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]):
        D[4 + k, i], D[4 + k, j] = 4 * L[j], 4 * L[i]
    return D


def natural_coordinates(Xe, p, L):
    """Newton's inverse of a curved 10-node tet's map at p, from the straight tet's guess L."""
    lam = np.array(L[1:], dtype=float)
    for _ in range(20):
        L = np.array([1 - lam.sum(), *lam])
        D = dshape10(L)
        step = np.linalg.solve(Xe.T @ (D[:, 1:] - D[:, [0]]), Xe.T @ shape10(L) - p)
        lam -= step
        if np.abs(step).max() < 1e-12:
            break
    return np.array([1 - lam.sum(), *lam])


def locate(X, rows, points):
    """For each point, the tet holding it and its natural coordinates there."""
    from scipy.spatial import cKDTree
    tree = cKDTree(X[rows[:, :4]].mean(axis=1))
    found = []
    for p in points:
        best = None
        for e in np.atleast_1d(tree.query(p, k=min(40, len(rows)))[1]):
            c = X[rows[e, :4]]
            lam = np.linalg.solve(np.column_stack([c[1] - c[0], c[2] - c[0], c[3] - c[0]]), p - c[0])
            L = np.array([1 - lam.sum(), *lam])
            if L.min() < -0.5:
                continue
            L = natural_coordinates(X[rows[e]], p, L)
            if best is None or L.min() > best[1].min():
                best = (e, L)
        found.append(best)
    return found


def into_sector(points, wedge_deg):
    """Each point turned about z onto the sector's mid-plane, and the angle turned (rad)."""
    phi = np.arctan2(points[:, 1], points[:, 0])
    turn = phi - math.radians(wedge_deg) / 2
    rho = np.hypot(points[:, 0], points[:, 1])
    return np.column_stack([rho * np.cos(phi - turn), rho * np.sin(phi - turn), points[:, 2]]), turn


def solve(case, workdir, forces, points=None):
    """Runs the case; returns {"forces_N", "indentation_mm" at `forces` (linear between
    increments), "u_mm": {force: displacement of each of `points` (n x 3)}, "nodes", "tets",
    "seconds", "increments"}."""
    wd = pathlib.Path(workdir) / case.name()
    wd.mkdir(parents=True, exist_ok=True)
    ids, X, tets = build_mesh(case, wd)
    rows = write_deck(case, wd, ids, X, tets)
    env = dict(os.environ, OMP_NUM_THREADS=str(case.threads),
               CCX_NPROC_EQUATION_SOLVER=str(case.threads))
    start = time.monotonic()
    with open(wd / "ccx.log", "w") as log:
        subprocess.run(["ccx", "-i", "job"], cwd=wd, env=env, stdout=log,
                       stderr=subprocess.STDOUT, check=False)
    seconds = time.monotonic() - start
    if "Job finished" not in (wd / "ccx.log").read_text():
        raise RuntimeError(f"ccx did not finish: see {wd / 'ccx.log'}")
    scale = 360.0 / case.wedge_deg
    f_of_t = {t: scale * f for t, f in read_forces(wd / "job.dat").items()}
    times = [0.0] + sorted(f_of_t)
    F = np.array([0.0] + [f_of_t[t] for t in times[1:]])
    d = case.max_indentation_mm * np.array(times)
    if F.max() < max(forces):
        raise RuntimeError(f"{case.name()}: {F.max():.3f} N at {d[-1]} mm, below {max(forces)} N")
    by_time = dict(read_displacements(wd / "job.frd"))
    faces = np.array([rows[e, list(FACES[f]) + list(FACE_EDGES[f])] for e, f in outer_faces(X, rows)])
    area = contact_areas(case, X, faces, [np.array([by_time[t].get(int(n), (0.0, 0.0, 0.0))
                                                    for n in ids]) for t in times[1:]], d[1:])
    result = {"forces_N": list(forces), "indentation_mm": [float(np.interp(f, F, d)) for f in forces],
              "contact_area_mm2": [float(np.interp(f, F, np.concatenate([[0.0], area])))
                                   for f in forces],
              "u_mm": {}, "nodes": len(ids), "tets": len(tets), "seconds": seconds,
              "increments": len(times) - 1, "curve": (d, F)}
    if points is not None:
        result["u_mm"] = _displacements(case, ids, X, rows, points, times, F, forces, by_time)
    return result


def face_rule(grid=16):
    """Centroids of a grid x grid split of the reference triangle, each of area 1 / (2 grid^2):
    the 6-node shape functions there and their derivatives in s and t."""
    st = [((i + a) / grid, (k + a) / grid) for i in range(grid) for k in range(grid - i)
          for a in ((1 / 3,) if i + k + 1 == grid else (1 / 3, 2 / 3))]
    s, t = np.array(st).T
    l1 = 1 - s - t
    N = np.stack([l1 * (2 * l1 - 1), s * (2 * s - 1), t * (2 * t - 1), 4 * l1 * s, 4 * s * t,
                  4 * t * l1], -1)
    z = 0 * s
    Ns = np.stack([1 - 4 * l1, 4 * s - 1, z, 4 * (l1 - s), 4 * t, -4 * t], -1)
    Nt = np.stack([1 - 4 * l1, z, 4 * t - 1, -4 * s, 4 * s, 4 * (l1 - t)], -1)
    return N, Ns, Nt, 0.5 / grid ** 2


def contact_areas(case, X, faces, displacements, indentations):
    """Deformed area of the 6-node `faces` (rows into X: corners, then edge nodes ab, bc, ca)
    that the indenter overlaps, per (displacement, indentation) pair; mm^2 over the whole dome
    (the sector's area times 360 / wedge_deg)."""
    N, Ns, Nt, w = face_rule()
    out = []
    for U, d in zip(displacements, indentations):
        P = (X + U)[faces]                                   # faces x 6 x 3
        p = np.einsum("qa,fax->fqx", N, P)
        dA = w * np.linalg.norm(np.cross(np.einsum("qa,fax->fqx", Ns, P),
                                         np.einsum("qa,fax->fqx", Nt, P)), axis=-1)
        inside = p[..., 2] > indenter_bottom(case, p[..., 0], p[..., 1]) - d
        out.append(360.0 / case.wedge_deg * float(dA[inside].sum()))
    return np.array(out)


def _displacements(case, ids, X, rows, points, times, F, forces, by_time):
    inside, turn = into_sector(np.asarray(points, dtype=float), case.wedge_deg)
    where = locate(X, rows, inside)
    history = [np.zeros((len(points), 3))]
    for t in times[1:]:
        U = np.array([by_time[t].get(int(n), (0.0, 0.0, 0.0)) for n in ids])
        u = np.array([shape10(L) @ U[rows[e]] for e, L in where])
        c, s = np.cos(turn), np.sin(turn)  # back from the sector to each point's azimuth
        history.append(np.column_stack([c * u[:, 0] - s * u[:, 1], s * u[:, 0] + c * u[:, 1], u[:, 2]]))
    out = {}
    for f in forces:
        k = int(np.searchsorted(F, f))
        w = (f - F[k - 1]) / (F[k] - F[k - 1])
        out[f] = history[k - 1] + w * (history[k] - history[k - 1])
    return out
