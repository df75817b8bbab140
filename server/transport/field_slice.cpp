#include "server/transport/field_slice.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <map>
#include <stdexcept>
#include <unordered_map>

namespace softshock::server {

namespace {

using Vec = std::array<double, 3>;

Vec cross(const Vec& a, const Vec& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double dot(const Vec& a, const Vec& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
Vec unit(const Vec& a) {
  const double n = std::sqrt(dot(a, a));
  return {a[0] / n, a[1] / n, a[2] / n};
}

}  // namespace

SlicePlane make_slice_plane(const Vec& point, const Vec& normal) {
  for (double c : point)
    if (!std::isfinite(c)) throw std::invalid_argument("the slice's point must be finite");
  const double length = std::sqrt(dot(normal, normal));
  if (!(length > 0) || !std::isfinite(length))
    throw std::invalid_argument("the slice's normal must be finite and not zero");
  SlicePlane p;
  p.origin = point;
  p.normal = unit(normal);
  // u: the coordinate axis least aligned with the normal (the first of equals), projected onto
  // the plane -- +x for the normal +z, so the z = 0 slice keeps the body's own x and y.
  int least = 0;
  for (int k = 1; k < 3; ++k)
    if (std::fabs(p.normal[k]) < std::fabs(p.normal[least])) least = k;
  Vec e{0, 0, 0};
  e[least] = 1;
  const double en = dot(e, p.normal);
  p.u = unit({e[0] - en * p.normal[0], e[1] - en * p.normal[1], e[2] - en * p.normal[2]});
  p.v = cross(p.normal, p.u);
  return p;
}

SliceMesh slice_tetrahedra(const std::vector<double>& x, const std::vector<double>& y,
                           const std::vector<double>& z,
                           const std::vector<std::array<int32_t, 4>>& tetrahedra,
                           const std::vector<double>& values, int components, bool node_field,
                           const SlicePlane& plane) {
  const std::size_t nc = static_cast<std::size_t>(components);
  if (components < 1 || x.size() != y.size() || x.size() != z.size() ||
      values.size() != (node_field ? x.size() : tetrahedra.size()) * nc) {
    throw std::invalid_argument("slice_tetrahedra: sizes of coordinates and values disagree");
  }
  // Signed distance of every node from the plane (NaN for a non-finite node).
  std::vector<double> d(x.size());
  for (std::size_t i = 0; i < x.size(); ++i)
    d[i] =
        dot({x[i] - plane.origin[0], y[i] - plane.origin[1], z[i] - plane.origin[2]}, plane.normal);
  SliceMesh out;
  // One section vertex per cut edge, shared by the tetrahedra around it.
  std::unordered_map<int64_t, int32_t> vertex_of_edge;
  auto cut = [&](int32_t a, int32_t b) {
    if (a > b) std::swap(a, b);
    const int64_t key = (static_cast<int64_t>(a) << 32) | static_cast<uint32_t>(b);
    auto it = vertex_of_edge.find(key);
    if (it != vertex_of_edge.end()) return it->second;
    const double s = d[a] / (d[a] - d[b]);  // the crossing along a -> b
    const Vec p{x[a] + s * (x[b] - x[a]) - plane.origin[0],
                y[a] + s * (y[b] - y[a]) - plane.origin[1],
                z[a] + s * (z[b] - z[a]) - plane.origin[2]};
    const auto id = static_cast<int32_t>(out.u.size());
    out.u.push_back(dot(p, plane.u));
    out.v.push_back(dot(p, plane.v));
    if (node_field)
      for (std::size_t c = 0; c < nc; ++c)
        out.values.push_back(values[a * nc + c] + s * (values[b * nc + c] - values[a * nc + c]));
    vertex_of_edge.emplace(key, id);
    return id;
  };
  for (std::size_t e = 0; e < tetrahedra.size(); ++e) {
    const auto& t = tetrahedra[e];
    std::array<int32_t, 4> below{}, above{};
    int nb = 0, na = 0;
    bool finite = true;
    for (int32_t i : t) {
      if (!std::isfinite(d[i])) finite = false;
      (d[i] < 0 ? below[nb++] : above[na++]) = i;  // a node on the plane counts as above
    }
    if (!finite || nb == 0 || na == 0) continue;
    std::vector<int32_t> polygon;  // 3 or 4 section vertices
    for (int i = 0; i < nb; ++i)
      for (int j = 0; j < na; ++j) polygon.push_back(cut(below[i], above[j]));
    // Order the polygon's vertices by angle about their mean (a convex section).
    double cu = 0, cv = 0;
    for (int32_t p : polygon) cu += out.u[p], cv += out.v[p];
    cu /= static_cast<double>(polygon.size()), cv /= static_cast<double>(polygon.size());
    std::sort(polygon.begin(), polygon.end(), [&](int32_t a, int32_t b) {
      return std::atan2(out.v[a] - cv, out.u[a] - cu) < std::atan2(out.v[b] - cv, out.u[b] - cu);
    });
    for (std::size_t k = 1; k + 1 < polygon.size(); ++k) {
      out.triangles.push_back({polygon[0], polygon[k], polygon[k + 1]});
      if (!node_field)
        for (std::size_t c = 0; c < nc; ++c) out.values.push_back(values[e * nc + c]);
    }
  }
  return out;
}

SurfaceMesh decimated_surface(const std::vector<double>& x, const std::vector<double>& y,
                              const std::vector<double>& z,
                              const std::vector<std::array<int32_t, 3>>& faces,
                              const std::vector<double>& values, int components, bool node_field,
                              std::size_t max_triangles) {
  const std::size_t nc = static_cast<std::size_t>(components);
  if (components < 1 || x.size() != y.size() || x.size() != z.size() ||
      values.size() != (node_field ? x.size() : faces.size()) * nc || max_triangles < 1) {
    throw std::invalid_argument("decimated_surface: sizes of coordinates and values disagree");
  }
  Vec lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const auto& f : faces)
    for (int32_t i : f) {
      const Vec p{x[i], y[i], z[i]};
      for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], p[k]), hi[k] = std::max(hi[k], p[k]);
    }
  // Finer grids keep more triangles: halve the cell until the next halving would exceed the
  // bound (a grid of n cells a side keeps O(n^2) surface triangles), starting from the whole
  // surface when it is within the bound already.
  SurfaceMesh best;
  auto cluster = [&](int cells) {
    SurfaceMesh s;
    const double span = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 1e-300});
    const double h = span / cells;
    std::map<std::array<int64_t, 3>, int32_t> cluster_of;
    std::vector<double> count;
    std::vector<int32_t> vertex_cluster(x.size(), -1);
    for (const auto& f : faces)
      for (int32_t i : f) {
        if (vertex_cluster[i] >= 0) continue;
        const std::array<int64_t, 3> key{static_cast<int64_t>(std::floor((x[i] - lo[0]) / h)),
                                         static_cast<int64_t>(std::floor((y[i] - lo[1]) / h)),
                                         static_cast<int64_t>(std::floor((z[i] - lo[2]) / h))};
        auto [it, inserted] = cluster_of.emplace(key, static_cast<int32_t>(count.size()));
        if (inserted) {
          count.push_back(0);
          s.xyz.insert(s.xyz.end(), {0.0, 0.0, 0.0});
          if (node_field) s.values.insert(s.values.end(), nc, 0.0);
        }
        const int32_t c = it->second;
        vertex_cluster[i] = c;
        count[c] += 1;
        s.xyz[3 * c] += x[i], s.xyz[3 * c + 1] += y[i], s.xyz[3 * c + 2] += z[i];
        if (node_field)
          for (std::size_t k = 0; k < nc; ++k) s.values[c * nc + k] += values[i * nc + k];
      }
    for (std::size_t c = 0; c < count.size(); ++c) {
      for (int k = 0; k < 3; ++k) s.xyz[3 * c + k] /= count[c];
      if (node_field)
        for (std::size_t k = 0; k < nc; ++k) s.values[c * nc + k] /= count[c];
    }
    std::map<std::array<int32_t, 3>, bool> seen;  // one triangle per set of clusters
    for (std::size_t f = 0; f < faces.size(); ++f) {
      const std::array<int32_t, 3> t{vertex_cluster[faces[f][0]], vertex_cluster[faces[f][1]],
                                     vertex_cluster[faces[f][2]]};
      if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
      std::array<int32_t, 3> key = t;
      std::sort(key.begin(), key.end());
      if (!seen.emplace(key, true).second) continue;
      s.triangles.push_back(t);
      if (!node_field)
        for (std::size_t k = 0; k < nc; ++k) s.values.push_back(values[f * nc + k]);
    }
    return s;
  };
  if (faces.size() <= max_triangles) {
    // No decimation: the surface itself, its vertices renumbered.
    SurfaceMesh s;
    std::vector<int32_t> id(x.size(), -1);
    for (std::size_t f = 0; f < faces.size(); ++f) {
      std::array<int32_t, 3> t{};
      for (int k = 0; k < 3; ++k) {
        const int32_t i = faces[f][k];
        if (id[i] < 0) {
          id[i] = static_cast<int32_t>(s.xyz.size() / 3);
          s.xyz.insert(s.xyz.end(), {x[i], y[i], z[i]});
          if (node_field)
            s.values.insert(s.values.end(), values.begin() + i * nc, values.begin() + (i + 1) * nc);
        }
        t[k] = id[i];
      }
      s.triangles.push_back(t);
      if (!node_field)
        s.values.insert(s.values.end(), values.begin() + f * nc, values.begin() + (f + 1) * nc);
    }
    return s;
  }
  for (int cells = 4; cells <= 4096; cells *= 2) {
    SurfaceMesh s = cluster(cells);
    if (s.triangles.size() > max_triangles) break;
    best = std::move(s);
  }
  return best;
}

}  // namespace softshock::server
