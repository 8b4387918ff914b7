// SPDX-License-Identifier: GPL-3.0-or-later
#include <femesher/Parallel.h>
#include <femesher/RunContext.h>
#include <femesher/SpatialHash.h>
#include <femesher/VecMath.h>
#include <femesher/stages/Junctions.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

namespace femesher {

namespace {

struct Eval {
  const IndicatorField& f;
  const PreprocessedVolume& vol;
  double value(int m, const Vec3& l) const { return f.eval(m, l); }
  /// Gradient with respect to canonical coordinates (mm).
  Vec3 grad(int m, const Vec3& l) const { return perMm(f.gradient(m, l)); }
  /// value and grad together (one lookup of the cell).
  double valueGrad(int m, const Vec3& l, Vec3& g) const {
    const double v = f.evalGradient(m, l, g);
    g = perMm(g);
    return v;
  }
  /// A gradient per local index unit, per mm.
  Vec3 perMm(const Vec3& g) const {
    return {g[0] / vol.spacing[0], g[1] / vol.spacing[1], g[2] / vol.spacing[2]};
  }
  Vec3 moveLocal(const Vec3& l, const Vec3& dc) const {  // add a canonical displacement
    return {l[0] + dc[0] / vol.spacing[0], l[1] + dc[1] / vol.spacing[1], l[2] + dc[2] / vol.spacing[2]};
  }
};


/// Gauss-Newton for f_l[0] = f_l[1] = ... = f_l[n-1] (n = 3 or 4) from `x` (local coordinates).
bool solveJunction(const Eval& e, const uint16_t* l, int n, Vec3& x, double tol) {
  for (int it = 0; it < 20; ++it) {
    double F[3];
    Vec3 J[3];
    Vec3 ga;
    const double fa = e.valueGrad(l[0], x, ga);
    double maxF = 0;
    for (int r = 0; r < n - 1; ++r) {
      Vec3 gr;
      F[r] = fa - e.valueGrad(l[r + 1], x, gr);
      J[r] = sub(ga, gr);
      maxF = std::max(maxF, std::fabs(F[r]));
    }
    if (maxF < tol) return true;
    Vec3 step{0, 0, 0};
    if (n == 3) {  // minimum-norm step: -J^T (J J^T)^-1 F
      const double a = dot(J[0], J[0]), b = dot(J[0], J[1]), d = dot(J[1], J[1]);
      const double det = a * d - b * b;
      if (std::fabs(det) < 1e-20) return false;
      const double y0 = (d * F[0] - b * F[1]) / det, y1 = (-b * F[0] + a * F[1]) / det;
      for (int k = 0; k < 3; ++k) step[k] = -(J[0][k] * y0 + J[1][k] * y1);
    } else {  // square system: Cramer's rule
      const Vec3 c12 = cross(J[1], J[2]), c20 = cross(J[2], J[0]), c01 = cross(J[0], J[1]);
      const double det = dot(J[0], c12);
      if (std::fabs(det) < 1e-20) return false;
      for (int k = 0; k < 3; ++k) step[k] = -(F[0] * c12[k] + F[1] * c20[k] + F[2] * c01[k]) / det;
    }
    // Damp large steps (the trilinear field is only piecewise smooth).
    const double len = std::sqrt(dot(step, step));
    const double maxStep = 0.5 * std::min({e.vol.spacing[0], e.vol.spacing[1], e.vol.spacing[2]});
    if (len > maxStep)
      for (auto& s : step) s *= maxStep / len;
    x = e.moveLocal(x, step);
  }
  return false;
}

/// True when labels l[0..n) are the n leading materials at x (ties within tol).
bool leading(const IndicatorField& f, const uint16_t* l, int n, const Vec3& x, double tol) {
  int cand[8];
  const int nc = f.cornerLabels(x, cand);
  double minOwn = 1e300;
  for (int i = 0; i < n; ++i) minOwn = std::min(minOwn, f.eval(l[i], x));
  for (int c = 0; c < nc; ++c) {
    if (std::find(l, l + n, uint16_t(cand[c])) != l + n) continue;
    if (f.eval(cand[c], x) > minOwn + tol) return false;
  }
  return true;
}


}  // namespace

bool locateJunctionPoint(const IndicatorField& field, const uint16_t* labels, int n, Vec3& local) {
  const PreprocessedVolume& vol = field.volume();
  const double smin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
  const double tol = 1e-4 * smin;
  return solveJunction(Eval{field, vol}, labels, n, local, tol) &&
         leading(field, labels, n, local, 10 * tol);
}

Junctions findJunctions(const IndicatorField& field, const SizingFunction& sizing,
                        const JunctionParameters& params, RunContext& ctx) {
  const PreprocessedVolume& vol = field.volume();
  const Eval e{field, vol};
  const double smin = std::min({vol.spacing[0], vol.spacing[1], vol.spacing[2]});
  const double tol = 1e-4 * smin;
  Junctions out;

  // --- Candidates: one located point per junction cell and label subset --------------------
  const int nx = vol.dims[0] - 1, ny = vol.dims[1] - 1, nz = vol.dims[2] - 1;
  const int threads = resolveThreads(ctx.threads());
  std::vector<std::vector<JunctionPoint>> perSlab(size_t(std::max(1, nz)));
  std::vector<size_t> triples(size_t(std::max(1, nz)), 0), quads(size_t(std::max(1, nz)), 0);
  parallelFor(size_t(std::max(0, nz)), threads, [&](size_t kb, size_t ke, int) {
    for (size_t k = kb; k < ke; ++k) {
      if (ctx.isCanceled()) return;
      for (int j = 0; j < ny; ++j)
        for (int i = 0; i < nx; ++i) {
          uint16_t lab[8];
          int n = 0;
          for (int c = 0; c < 8; ++c) {
            const uint16_t l = vol.at(i + (c & 1), j + ((c >> 1) & 1), int(k) + ((c >> 2) & 1));
            if (std::find(lab, lab + n, l) == lab + n) lab[n++] = l;
          }
          if (n < 3) continue;
          for (int a = 1; a < n; ++a)  // insertion sort (n <= 8)
            for (int b = a; b > 0 && lab[b - 1] > lab[b]; --b) std::swap(lab[b - 1], lab[b]);
          ++triples[k];
          if (n >= 4) ++quads[k];
          const Vec3 centre{i + 0.5, j + 0.5, k + 0.5};
          auto inCell = [&](const Vec3& x) {
            return x[0] >= i - 0.25 && x[0] <= i + 1.25 && x[1] >= j - 0.25 && x[1] <= j + 1.25 &&
                   x[2] >= k - 0.25 && x[2] <= k + 1.25;
          };
          for (int s = 3; s <= std::min(n, 4); ++s) {
            // every subset of size s
            std::vector<int> idx(s);
            for (int q = 0; q < s; ++q) idx[q] = q;
            for (;;) {
              uint16_t sub[4];
              for (int q = 0; q < s; ++q) sub[q] = lab[idx[q]];
              Vec3 x = centre;
              if (solveJunction(e, sub, s, x, tol) && inCell(x) && leading(field, sub, s, x, 10 * tol)) {
                JunctionPoint p;
                p.local = x;
                p.count = uint8_t(s);
                for (int q = 0; q < s; ++q) p.labels[q] = sub[q];
                perSlab[k].push_back(p);
              }
              int q = s - 1;
              while (q >= 0 && idx[q] == n - s + q) --q;
              if (q < 0) break;
              ++idx[q];
              for (int r = q + 1; r < s; ++r) idx[r] = idx[r - 1] + 1;
            }
          }
        }
    }
  }, std::max(1, nz));  // one chunk per plane of cells: junction cells cluster in a few
  ctx.checkCancel();
  for (size_t k = 0; k < perSlab.size(); ++k) {
    out.candidates.insert(out.candidates.end(), perSlab[k].begin(), perSlab[k].end());
    out.tripleCells += triples[k];
    out.quadrupleCells += quads[k];
  }
  ctx.progress(0.5);

  // --- Sampling: quadruple points first, then triple lines at the sizing field's spacing -------
  auto canonical = [&](const JunctionPoint& p) { return vol.localToCanonical(p.local); };
  std::vector<uint32_t> order(out.candidates.size());
  for (uint32_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    return out.candidates[a].count > out.candidates[b].count;
  });
  double hMax = 0;
  for (const auto& p : out.candidates) hMax = std::max(hMax, params.spacingFactor * sizing(canonical(p)));
  const double cell = std::max(hMax, smin);
  std::unordered_map<CellKey, std::vector<uint32_t>, CellKeyHash> grid;
  auto keyOf = [&](const Vec3& c) {
    return CellKey{int64_t(std::floor(c[0] / cell)), int64_t(std::floor(c[1] / cell)),
               int64_t(std::floor(c[2] / cell))};
  };
  for (uint32_t i : order) {
    const JunctionPoint& p = out.candidates[i];
    const Vec3 c = canonical(p);
    const double r = 0.75 * params.spacingFactor * sizing(c);
    const CellKey key = keyOf(c);
    bool ok = true;
    for (int dz = -1; dz <= 1 && ok; ++dz)
      for (int dy = -1; dy <= 1 && ok; ++dy)
        for (int dx = -1; dx <= 1 && ok; ++dx) {
          auto it = grid.find({key.x + dx, key.y + dy, key.z + dz});
          if (it == grid.end()) continue;
          for (uint32_t j : it->second) {
            const JunctionPoint& q = out.particles[j];
            const Vec3 d = sub(c, canonical(q));
            const double d2 = dot(d, d);
            const bool sameLine = p.count == 3 && q.count == 3 && p.labels == q.labels;
            // Quadruple points keep a neighbourhood free; distinct lines may come close.
            const double rr = sameLine || q.count == 4 ? r : 0.3 * r;
            if (d2 < rr * rr) {
              ok = false;
              break;
            }
          }
        }
    if (!ok) continue;
    grid[key].push_back(uint32_t(out.particles.size()));
    out.particles.push_back(p);
    if (p.count == 4) ++out.quadruplePoints;
  }
  ctx.progress(0.7);

  // --- 1-D relaxation along each triple line (Jacobi; quadruple points stay fixed) -----------
  std::map<std::array<uint16_t, 4>, std::vector<uint32_t>> lines;
  for (uint32_t i = 0; i < out.particles.size(); ++i)
    if (out.particles[i].count == 3) lines[out.particles[i].labels].push_back(i);
  struct LineParticle {
    const std::array<uint16_t, 4>* labels;
    const std::vector<uint32_t>* ids;
    uint32_t particle;
  };
  std::vector<LineParticle> work;  // the particles of lines of at least three, line by line
  for (const auto& [labels, ids] : lines)
    if (ids.size() >= 3)
      for (uint32_t i : ids) work.push_back({&labels, &ids, i});
  for (int it = 0; it < params.relaxIterations; ++it) {
    ctx.checkCancel();
    std::vector<Vec3> next(out.particles.size());
    for (uint32_t i = 0; i < out.particles.size(); ++i) next[i] = out.particles[i].local;
    // Every particle's move reads the previous positions only (Jacobi): in parallel, each
    // writing its own next[i].
    parallelFor(work.size(), threads, [&](size_t wb, size_t we, int) {
      for (size_t w = wb; w < we; ++w) {
        const std::array<uint16_t, 4>& labels = *work[w].labels;
        const std::vector<uint32_t>& ids = *work[w].ids;
        const uint32_t i = work[w].particle;
        const JunctionPoint& p = out.particles[i];
        const Vec3 c = canonical(p);
        const double h = params.spacingFactor * sizing(c);
        // tangent of the line
        const Vec3 g1 = sub(e.grad(labels[0], p.local), e.grad(labels[1], p.local));
        const Vec3 g2 = sub(e.grad(labels[0], p.local), e.grad(labels[2], p.local));
        Vec3 t = cross(g1, g2);
        const double tl = std::sqrt(dot(t, t));
        if (tl < 1e-12) continue;
        for (auto& v : t) v /= tl;
        // nearest neighbour ahead and behind along t, within 2.5 h
        double ahead = 1e300, behind = -1e300;
        for (uint32_t j : ids) {
          if (j == i) continue;
          const Vec3 d = sub(canonical(out.particles[j]), c);
          const double dd = dot(d, d);
          if (dd > 6.25 * h * h) continue;
          const double s = dot(d, t);
          if (s > 0 && s < ahead) ahead = s;
          if (s < 0 && s > behind) behind = s;
        }
        if (ahead > 1e299 || behind < -1e299) continue;  // line end: keep
        const double move = 0.5 * (0.5 * (ahead + behind));
        Vec3 x = e.moveLocal(p.local, {t[0] * move, t[1] * move, t[2] * move});
        const uint16_t* l = labels.data();
        if (solveJunction(e, l, 3, x, tol) && leading(field, l, 3, x, 10 * tol)) next[i] = x;
      }
    }, 64);
    for (uint32_t i = 0; i < out.particles.size(); ++i) out.particles[i].local = next[i];
    ctx.progress(0.7 + 0.3 * (it + 1) / std::max(1, params.relaxIterations));
  }
  return out;
}

ReportCounts reportCounts(const Junctions& j) {
  return {{"junction_cells", double(j.tripleCells)},
          {"quadruple_cells", double(j.quadrupleCells)},
          {"junction_particles", double(j.particles.size())},
          {"quadruple_points", double(j.quadruplePoints)}};
}

}  // namespace femesher
