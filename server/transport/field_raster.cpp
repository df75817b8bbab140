#include "server/transport/field_raster.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace softshock::server {

std::vector<double> rasterize(const std::vector<double>& x, const std::vector<double>& y,
                              const std::vector<std::array<int32_t, 3>>& triangles,
                              const std::vector<double>& values, int components, bool node_field,
                              int nx, int ny, RasterBox& box) {
  if (nx < 1 || ny < 1 || components < 1) throw std::invalid_argument("rasterize: bad size");
  const std::size_t nc = static_cast<std::size_t>(components);
  const std::size_t expected = (node_field ? x.size() : triangles.size()) * nc;
  if (x.size() != y.size() || values.size() != expected) {
    throw std::invalid_argument("rasterize: sizes of coordinates and values disagree");
  }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> out(static_cast<std::size_t>(nx) * ny * nc, nan);
  if (triangles.empty() || x.empty()) {
    box = {};
    return out;
  }

  // A diverged run can leave non-finite coordinates in a frame: such nodes (and the triangles
  // that use them) are left out, so the box and the bucket indices stay finite.
  auto finite_node = [&](int32_t n) { return std::isfinite(x[n]) && std::isfinite(y[n]); };
  box = {};
  bool any = false;
  for (std::size_t n = 0; n < x.size(); ++n) {
    if (!finite_node(static_cast<int32_t>(n))) continue;
    box.x_min = any ? std::min(box.x_min, x[n]) : x[n];
    box.x_max = any ? std::max(box.x_max, x[n]) : x[n];
    box.y_min = any ? std::min(box.y_min, y[n]) : y[n];
    box.y_max = any ? std::max(box.y_max, y[n]) : y[n];
    any = true;
  }
  if (!any) return out;
  const double width = std::max(box.x_max - box.x_min, 1e-300);
  const double height = std::max(box.y_max - box.y_min, 1e-300);

  // Uniform bucket grid over the triangles' bounding boxes (CSR lists), about one triangle per
  // bucket, so each cell centre tests a handful of triangles.
  const int g =
      std::clamp(static_cast<int>(std::sqrt(static_cast<double>(triangles.size()))), 1, 1024);
  const double bw = width / g, bh = height / g;
  // Clamped as a double before the conversion: a quotient that overflows int (or is NaN)
  // must never reach static_cast<int>.
  auto bucket = [g](double q) {
    if (!(q > 0)) return 0;
    if (q >= g - 1) return g - 1;
    return static_cast<int>(q);
  };
  auto bucket_x = [&](double v) { return bucket((v - box.x_min) / bw); };
  auto bucket_y = [&](double v) { return bucket((v - box.y_min) / bh); };
  struct Range {
    int i0, i1, j0, j1;
  };
  std::vector<Range> ranges(triangles.size(), Range{0, -1, 0, -1});  // empty: left out
  std::size_t entries = 0;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const auto& tri = triangles[t];
    if (!finite_node(tri[0]) || !finite_node(tri[1]) || !finite_node(tri[2])) continue;
    double lo_x = x[tri[0]], hi_x = lo_x, lo_y = y[tri[0]], hi_y = lo_y;
    for (int k = 1; k < 3; ++k) {
      lo_x = std::min(lo_x, x[tri[k]]);
      hi_x = std::max(hi_x, x[tri[k]]);
      lo_y = std::min(lo_y, y[tri[k]]);
      hi_y = std::max(hi_y, y[tri[k]]);
    }
    ranges[t] = {bucket_x(lo_x), bucket_x(hi_x), bucket_y(lo_y), bucket_y(hi_y)};
    entries += static_cast<std::size_t>(ranges[t].i1 - ranges[t].i0 + 1) *
               static_cast<std::size_t>(ranges[t].j1 - ranges[t].j0 + 1);
  }
  // A badly tangled body puts every triangle in every bucket (n^2 entries): refuse that rather
  // than overflow the counters or exhaust memory.
  if (entries > kMaxRasterBucketEntries) {
    throw std::length_error("rasterize: the deformed mesh is too tangled to resample (" +
                            std::to_string(entries) + " bucket entries, at most " +
                            std::to_string(kMaxRasterBucketEntries) + ")");
  }
  std::vector<int64_t> start(static_cast<std::size_t>(g) * g + 1, 0);
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (int j = ranges[t].j0; j <= ranges[t].j1; ++j) {
      for (int i = ranges[t].i0; i <= ranges[t].i1; ++i) ++start[j * g + i + 1];
    }
  }
  for (std::size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
  std::vector<int32_t> items(static_cast<std::size_t>(start.back()));
  std::vector<int64_t> fill(start.begin(), start.end() - 1);
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (int j = ranges[t].j0; j <= ranges[t].j1; ++j) {
      for (int i = ranges[t].i0; i <= ranges[t].i1; ++i) {
        items[fill[j * g + i]++] = static_cast<int32_t>(t);
      }
    }
  }

  // A point on a shared edge belongs to either neighbour; the tolerance closes the hairline
  // gaps rounding would leave between them.
  constexpr double kTolerance = 1e-10;
  const double dx = width / nx, dy = height / ny;
  for (int j = 0; j < ny; ++j) {
    const double py = box.y_min + (j + 0.5) * dy;
    const int by = bucket_y(py);
    for (int i = 0; i < nx; ++i) {
      const double px = box.x_min + (i + 0.5) * dx;
      const int b = by * g + bucket_x(px);
      for (int64_t k = start[b]; k < start[b + 1]; ++k) {
        const auto& tri = triangles[items[k]];
        const double ax = x[tri[0]], ay = y[tri[0]];
        const double bx = x[tri[1]], by2 = y[tri[1]];
        const double cx = x[tri[2]], cy = y[tri[2]];
        const double det = (bx - ax) * (cy - ay) - (cx - ax) * (by2 - ay);
        if (det == 0) continue;
        // Barycentric weights by signed sub-areas; dividing by det makes them orientation-free.
        const double l1 = ((bx - px) * (cy - py) - (cx - px) * (by2 - py)) / det;
        const double l2 = ((cx - px) * (ay - py) - (ax - px) * (cy - py)) / det;
        const double l3 = 1.0 - l1 - l2;
        if (l1 < -kTolerance || l2 < -kTolerance || l3 < -kTolerance) continue;
        double* cell = &out[(static_cast<std::size_t>(j) * nx + i) * nc];
        for (std::size_t c = 0; c < nc; ++c) {
          cell[c] = node_field ? l1 * values[tri[0] * nc + c] + l2 * values[tri[1] * nc + c] +
                                     l3 * values[tri[2] * nc + c]
                               : values[items[k] * nc + c];
        }
        break;
      }
    }
  }
  return out;
}

}  // namespace softshock::server
