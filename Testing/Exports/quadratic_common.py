# SPDX-License-Identifier: GPL-3.0-or-later
"""What the second-order export tests compute on a written 10-node mesh, independently of FEMesher:
the Jacobian determinant of the quadratic map at the 4 corners, 6 mid-edge nodes and centroid of
every element, the edges on interfaces and the outer boundary (from the element faces and their
materials), and the distance of a point from the interface triangles of a reference mesh (a fine
linear mesh of the same label map, whose interface lies on the same smooth interfaces).
Node order: C3D10 / VTK / meshio's tetra10 (mid-edge nodes on edges 01, 12, 20, 03, 13, 23)."""
import numpy as np

EDGES = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
FACES = [(1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1)]  # opposite corner 0, 1, 2, 3
CHECK_POINTS = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (0.5, 0, 0), (0.5, 0.5, 0), (0, 0.5, 0),
                (0, 0, 0.5), (0.5, 0, 0.5), (0, 0.5, 0.5), (0.25, 0.25, 0.25)]


def tet10_dets(x):
    """det J of the quadratic map of every element (x: n x 10 x 3) at CHECK_POINTS: n x 11."""
    out = []
    for r, s, t in CHECK_POINTS:
        u = 1 - r - s - t
        dr = np.array([1 - 4 * u, 4 * r - 1, 0, 0, 4 * (u - r), 4 * s, -4 * s, -4 * t, 4 * t, 0])
        ds = np.array([1 - 4 * u, 0, 4 * s - 1, 0, -4 * r, 4 * r, 4 * (u - s), -4 * t, 0, 4 * t])
        dt = np.array([1 - 4 * u, 0, 0, 4 * t - 1, -4 * r, 0, -4 * s, 4 * (u - t), 4 * r, 4 * s])
        J = np.stack([np.einsum("a,eac->ec", d, x) for d in (dr, ds, dt)], axis=2)
        out.append(np.linalg.det(J))
    return np.stack(out, axis=1)


def straight_dets(x):
    """6 x the volume of each element's corner tet (det J of the straight-sided element)."""
    return np.einsum("ij,ij->i", x[:, 1] - x[:, 0], np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]))


def jacobian_figures(x):
    """(smallest det J over the straight-sided one, smallest min/max det J of an element)."""
    d = tet10_dets(x)
    s = straight_dets(x)
    return float((d.min(axis=1) / s).min()), float((d.min(axis=1) / d.max(axis=1)).min())


class Tet10Mesh:
    """cells: n x 10 node indices (C3D10 order), labels: n material ids, points: m x 3."""

    def __init__(self, points, cells, labels):
        self.points, self.cells, self.labels = np.asarray(points, float), np.asarray(cells), np.asarray(labels)
        # Faces of the corner tets -> elements holding them.
        faces = {}
        for e, c in enumerate(self.cells):
            for k, f in enumerate(FACES):
                faces.setdefault(tuple(sorted(int(c[i]) for i in f)), []).append((e, k))
        self.faces = faces
        # Edge -> mid-edge nodes the elements give it (one each when conformal).
        self.mid = {}
        for c in self.cells:
            for k, (a, b) in enumerate(EDGES):
                self.mid.setdefault((min(c[a], c[b]), max(c[a], c[b])), set()).add(int(c[4 + k]))
        # Edge -> material pairs (lo, hi) of its interface / outer faces (0 = outside).
        self.edge_pairs = {}
        self.face_pair = {}
        for f, owners in faces.items():
            ls = sorted(int(self.labels[e]) for e, _ in owners)
            if len(owners) == 1:
                pair = (0, ls[0])
            elif ls[0] != ls[1]:
                pair = (ls[0], ls[1])
            else:
                continue
            self.face_pair[f] = pair
            for a, b in ((f[0], f[1]), (f[1], f[2]), (f[0], f[2])):
                self.edge_pairs.setdefault((min(a, b), max(a, b)), set()).add(pair)

    def face_normal(self, f, pair):
        """Unit normal of face f pointing into the element of the pair's higher label."""
        p = self.points[list(f)]
        n = np.cross(p[1] - p[0], p[2] - p[0])
        for e, k in self.faces[f]:
            if self.labels[e] == pair[1]:
                opp = self.points[self.cells[e][k]]
                if np.dot(n, opp - p[0]) < 0:
                    n = -n
        return n / np.linalg.norm(n)


def interface_triangles(points, cells, labels):
    """Interface and outer-boundary triangles of a tet mesh (corner nodes of `cells`), by material
    pair (lo, hi), 0 = outside: {pair: array n x 3 x 3 of vertex coordinates}."""
    faces = {}
    for e, c in enumerate(cells):
        for f in FACES:
            faces.setdefault(tuple(sorted(int(c[i]) for i in f)), []).append(int(labels[e]))
    out = {}
    for f, ls in faces.items():
        ls = sorted(ls)
        pair = (0, ls[0]) if len(ls) == 1 else (ls[0], ls[1]) if ls[0] != ls[1] else None
        if pair:
            out.setdefault(pair, []).append(points[list(f)])
    return {k: np.array(v) for k, v in out.items()}


def point_triangle_distance(p, T):
    """Distance from point p to each triangle of T (n x 3 x 3): the closest point on the triangle
    (Voronoi regions of its vertices, edges and face, after Ericson, Real-Time Collision Detection)."""
    a, b, c = T[:, 0], T[:, 1], T[:, 2]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    denom = va + vb + vc
    with np.errstate(divide="ignore", invalid="ignore"):
        v = vb / denom
        w = vc / denom
    q = a + ab * v[:, None] + ac * w[:, None]  # inside the face
    with np.errstate(divide="ignore", invalid="ignore"):
        tab = np.clip(d1 / (d1 - d3), 0, 1)
        tac = np.clip(d2 / (d2 - d6), 0, 1)
        tbc = np.clip((d4 - d3) / ((d4 - d3) + (d5 - d6)), 0, 1)
    e_ab = a + ab * tab[:, None]
    e_ac = a + ac * tac[:, None]
    e_bc = b + (c - b) * tbc[:, None]
    cand = np.stack([q, e_ab, e_ac, e_bc, a, b, c], axis=1)
    inside = (va >= 0) & (vb >= 0) & (vc >= 0) & (denom > 0)
    dist = np.linalg.norm(cand - p, axis=2)
    dist[~inside, 0] = np.inf
    return dist.min(axis=1)


class SurfaceDistance:
    """Distance from points to the triangles of one material pair of a (fine) reference mesh."""

    def __init__(self, triangles, cell=2.0):
        self.cell = cell
        self.tris = triangles
        self.grid = {}
        for pair, T in triangles.items():
            lo, hi = np.floor(T.min(axis=1) / cell).astype(int), np.floor(T.max(axis=1) / cell).astype(int)
            g = self.grid.setdefault(pair, {})
            for i, (l, h) in enumerate(zip(lo, hi)):
                for x in range(l[0], h[0] + 1):
                    for y in range(l[1], h[1] + 1):
                        for z in range(l[2], h[2] + 1):
                            g.setdefault((x, y, z), []).append(i)

    def __call__(self, p, pair):
        """Distance from p to the pair's triangles within a cell of it (inf when none)."""
        g = self.grid.get(pair, {})
        k = np.floor(p / self.cell).astype(int)
        idx = set()
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    idx.update(g.get((k[0] + dx, k[1] + dy, k[2] + dz), ()))
        if not idx:
            return np.inf
        return float(point_triangle_distance(p, self.tris[pair][sorted(idx)]).min())
