// Resampling of a field on the deformed triangle mesh onto a regular nx x ny raster covering
// the deformed bounding box (GetField's raster mode). Element fields are piecewise constant,
// node fields are interpolated barycentrically; cells whose centre lies in no triangle are NaN.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace softshock::server {

struct RasterBox {
  double x_min = 0, x_max = 0, y_min = 0, y_max = 0;
};

// Bucket entries (triangle x bucket pairs) rasterize() accepts: 4 bytes each.
inline constexpr std::size_t kMaxRasterBucketEntries = 64u << 20;

// x, y: deformed node coordinates (nodes with a non-finite coordinate, and their triangles,
// are left out); values: per node (node_field) or per element, with
// `components` interleaved values each. Returns nx * ny * components values, row-major in j
// (cell (i, j) at index (j * nx + i) * components + c); `box` receives the raster extent.
// Throws std::length_error when the deformed mesh is too tangled to bucket (see above).
std::vector<double> rasterize(const std::vector<double>& x, const std::vector<double>& y,
                              const std::vector<std::array<int32_t, 3>>& triangles,
                              const std::vector<double>& values, int components, bool node_field,
                              int nx, int ny, RasterBox& box);

}  // namespace softshock::server
