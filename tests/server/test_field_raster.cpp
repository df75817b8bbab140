// Raster resampling of mesh fields (GetField's raster mode).
#include <gtest/gtest.h>

#include <cmath>

#include "server/transport/field_raster.hpp"
#include "server/transport/field_slice.hpp"
#include "tests/solver/tet_box.hpp"

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

// ---- 3-D: slices and the decimated surface (field_slice.hpp) ----------------------------------

// A 2 x 1 x 1 box of tetrahedra, sheared so the slice's geometry is not the mesh's.
Mesh sheared_box() {
  Mesh m = softshock::testing::tet_box(2.0, 1.0, 1.0, 8, 4, 4);
  for (std::size_t i = 0; i < m.node_count(); ++i) m.x[i] += 0.3 * m.z[i];
  return m;
}

// A plane z = 0.4 through the box: the section is the box's cross-section (2 x 1, shifted by the
// shear); a linear node field is exact at every cell centre inside it, an element field is the
// value of the tetrahedron the centre lies in, and cells outside are NaN.
TEST(FieldSlice, APlaneCutsTheBoxAndInterpolatesLinearFieldsExactly) {
  const Mesh m = sheared_box();
  std::vector<double> f(m.node_count());
  for (std::size_t i = 0; i < f.size(); ++i) f[i] = 1 + 2 * m.x[i] - m.y[i] + 5 * m.z[i];
  const SlicePlane plane = make_slice_plane({0, 0, 0.4}, {0, 0, 3});
  EXPECT_DOUBLE_EQ(plane.u[0], 1.0);  // z = const: the body's own x and y
  EXPECT_DOUBLE_EQ(plane.v[1], 1.0);
  const SliceMesh s = slice_tetrahedra(m.x, m.y, m.z, m.tetrahedra, f, 1, true, plane);
  ASSERT_FALSE(s.triangles.empty());
  double area = 0;
  for (const auto& t : s.triangles)
    area += 0.5 * std::fabs((s.u[t[1]] - s.u[t[0]]) * (s.v[t[2]] - s.v[t[0]]) -
                            (s.u[t[2]] - s.u[t[0]]) * (s.v[t[1]] - s.v[t[0]]));
  EXPECT_NEAR(area, 2.0, 1e-12);  // the section of every cut tetrahedron, no overlaps
  RasterBox box;
  const int nx = 40, ny = 20;
  const auto r = rasterize(s.u, s.v, s.triangles, s.values, 1, true, nx, ny, box);
  EXPECT_NEAR(box.x_min, 0.12, 1e-12);  // x shifted by 0.3 z
  EXPECT_NEAR(box.x_max, 2.12, 1e-12);
  int inside = 0;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const double u = box.x_min + (i + 0.5) * (box.x_max - box.x_min) / nx;
      const double v = box.y_min + (j + 0.5) * (box.y_max - box.y_min) / ny;
      const double value = r[j * nx + i];
      if (std::isnan(value)) continue;
      ++inside;
      EXPECT_NEAR(value, 1 + 2 * u - v + 5 * 0.4, 1e-12);
    }
  EXPECT_EQ(inside, nx * ny);  // the section fills its own box
  // An element field: each section triangle carries its tetrahedron's value.
  std::vector<double> g(m.tetrahedra.size());
  for (std::size_t e = 0; e < g.size(); ++e) g[e] = static_cast<double>(e);
  const SliceMesh se = slice_tetrahedra(m.x, m.y, m.z, m.tetrahedra, g, 1, false, plane);
  EXPECT_EQ(se.values.size(), se.triangles.size());
  // A plane that misses the body gives no section.
  EXPECT_TRUE(slice_tetrahedra(m.x, m.y, m.z, m.tetrahedra, f, 1, true,
                               make_slice_plane({0, 0, 5}, {0, 0, 1}))
                  .triangles.empty());
  EXPECT_THROW(make_slice_plane({0, 0, 0}, {0, 0, 0}), std::invalid_argument);
}

// An oblique plane: node vectors (3 components) still interpolate exactly.
TEST(FieldSlice, ObliquePlanesAndVectorFields) {
  const Mesh m = sheared_box();
  std::vector<double> f;
  for (std::size_t i = 0; i < m.node_count(); ++i)
    f.insert(f.end(), {m.x[i], m.y[i] - m.z[i], 2.0});
  const SlicePlane plane = make_slice_plane({1, 0.5, 0.5}, {1, 1, 1});
  EXPECT_NEAR(
      plane.u[0] * plane.normal[0] + plane.u[1] * plane.normal[1] + plane.u[2] * plane.normal[2],
      0.0, 1e-15);
  const SliceMesh s = slice_tetrahedra(m.x, m.y, m.z, m.tetrahedra, f, 3, true, plane);
  ASSERT_FALSE(s.triangles.empty());
  for (std::size_t k = 0; k < s.u.size(); ++k) {  // each section vertex carries f at its point
    const double px = plane.origin[0] + s.u[k] * plane.u[0] + s.v[k] * plane.v[0];
    const double py = plane.origin[1] + s.u[k] * plane.u[1] + s.v[k] * plane.v[1];
    const double pz = plane.origin[2] + s.u[k] * plane.u[2] + s.v[k] * plane.v[2];
    EXPECT_NEAR(s.values[3 * k], px, 1e-12);
    EXPECT_NEAR(s.values[3 * k + 1], py - pz, 1e-12);
    EXPECT_NEAR(s.values[3 * k + 2], 2.0, 1e-12);
  }
}

// The surface: whole when within the bound; decimated to at most the bound otherwise, keeping its
// extent and (roughly) its area, node fields averaged, element fields kept per triangle.
TEST(FieldSlice, SurfaceDecimatedWithinItsBound) {
  const Mesh m = softshock::testing::tet_box(1.0, 1.0, 1.0, 12, 12, 12);
  std::vector<double> f(m.node_count()), per_face(m.boundary_faces.size(), 7.0);
  for (std::size_t i = 0; i < f.size(); ++i) f[i] = m.x[i] + m.y[i];
  auto area = [](const SurfaceMesh& s) {
    double a = 0;
    for (const auto& t : s.triangles) {
      const double* p = &s.xyz[3 * t[0]];
      const double* q = &s.xyz[3 * t[1]];
      const double* r = &s.xyz[3 * t[2]];
      const double ux = q[0] - p[0], uy = q[1] - p[1], uz = q[2] - p[2];
      const double vx = r[0] - p[0], vy = r[1] - p[1], vz = r[2] - p[2];
      const double cx = uy * vz - uz * vy, cy = uz * vx - ux * vz, cz = ux * vy - uy * vx;
      a += 0.5 * std::sqrt(cx * cx + cy * cy + cz * cz);
    }
    return a;
  };
  const SurfaceMesh whole =
      decimated_surface(m.x, m.y, m.z, m.boundary_faces, f, 1, true, 1'000'000);
  EXPECT_EQ(whole.triangles.size(), m.boundary_faces.size());
  EXPECT_NEAR(area(whole), 6.0, 1e-12);
  const std::size_t bound = 200;
  const SurfaceMesh coarse = decimated_surface(m.x, m.y, m.z, m.boundary_faces, f, 1, true, bound);
  ASSERT_FALSE(coarse.triangles.empty());
  EXPECT_LE(coarse.triangles.size(), bound);
  EXPECT_EQ(coarse.values.size(), coarse.xyz.size() / 3);
  EXPECT_NEAR(area(coarse), 6.0, 1.5);  // clustered corners cut the cube's edges a little
  for (std::size_t k = 0; k < coarse.values.size(); ++k)  // a mean of x + y over the cluster
    EXPECT_NEAR(coarse.values[k], coarse.xyz[3 * k] + coarse.xyz[3 * k + 1], 1e-12);
  const SurfaceMesh by_face =
      decimated_surface(m.x, m.y, m.z, m.boundary_faces, per_face, 1, false, bound);
  EXPECT_EQ(by_face.values.size(), by_face.triangles.size());
}

}  // namespace
}  // namespace softshock::server
