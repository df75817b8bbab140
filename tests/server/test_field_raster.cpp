// Raster resampling of mesh fields (GetField's raster mode).
#include <gtest/gtest.h>

#include <cmath>

#include "server/transport/field_raster.hpp"

namespace softshock::server {
namespace {

// Unit square split into two triangles, plus a triangle hanging off to the right so part of
// the bounding box lies outside the body.
struct Body {
  std::vector<double> x{0, 1, 1, 0, 2};
  std::vector<double> y{0, 0, 1, 1, 0};
  std::vector<std::array<int32_t, 3>> tris{{0, 1, 2}, {0, 2, 3}, {1, 4, 2}};
};

TEST(FieldRaster, ElementFieldsArePiecewiseConstantAndOutsideIsNaN) {
  Body b;
  RasterBox box;
  const auto r = rasterize(b.x, b.y, b.tris, {10, 20, 30}, 1, false, 8, 4, box);
  ASSERT_EQ(r.size(), 32u);
  EXPECT_DOUBLE_EQ(box.x_min, 0);
  EXPECT_DOUBLE_EQ(box.x_max, 2);
  EXPECT_DOUBLE_EQ(box.y_max, 1);
  // Cell (i, j) centre = ((i + 0.5) / 4, (j + 0.5) / 4).
  EXPECT_EQ(r[0 * 8 + 1], 10);            // (0.375, 0.125): below the diagonal
  EXPECT_EQ(r[3 * 8 + 0], 20);            // (0.125, 0.875): above it
  EXPECT_EQ(r[0 * 8 + 4], 30);            // (1.125, 0.125): in the hanging triangle
  EXPECT_TRUE(std::isnan(r[3 * 8 + 7]));  // (1.875, 0.875): outside
}

TEST(FieldRaster, NodeFieldsInterpolateLinearFunctionsExactly) {
  Body b;
  std::vector<double> v;  // two components: (x + 2y, 3 - x)
  for (std::size_t i = 0; i < b.x.size(); ++i) {
    v.push_back(b.x[i] + 2 * b.y[i]);
    v.push_back(3 - b.x[i]);
  }
  RasterBox box;
  const int nx = 16, ny = 8;
  const auto r = rasterize(b.x, b.y, b.tris, v, 2, true, nx, ny, box);
  int inside = 0;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const double px = (i + 0.5) * 2.0 / nx, py = (j + 0.5) * 1.0 / ny;
      const double* c = &r[(j * nx + i) * 2];
      if (std::isnan(c[0])) continue;
      ++inside;
      EXPECT_NEAR(c[0], px + 2 * py, 1e-12);
      EXPECT_NEAR(c[1], 3 - px, 1e-12);
    }
  }
  // The body covers 1.5 of the 2 box units: about 3/4 of the cells.
  EXPECT_NEAR(inside, nx * ny * 3 / 4, nx);
}

TEST(FieldRaster, RejectsMismatchedSizes) {
  Body b;
  RasterBox box;
  EXPECT_THROW(rasterize(b.x, b.y, b.tris, {1, 2}, 1, false, 4, 4, box), std::invalid_argument);
  EXPECT_THROW(rasterize(b.x, b.y, b.tris, {1, 2, 3}, 1, false, 0, 4, box), std::invalid_argument);
}

}  // namespace
}  // namespace softshock::server
