// 3-D meshes of linear tetrahedra: checks, orientation and outward boundary faces; Morton
// order; structured (Kuhn) boxes, flat and corrugated; volume and centroid.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "solver/mesh.hpp"

namespace softshock {
namespace {

// A tetrahedron counts as degenerate when |6 V| is below this fraction of L^3, L being the
// largest side of the mesh's bounding box (the 2-D rule's analogue). Rounding in the triple
// product of a coplanar quadruple is ~1e-16 L^3, so 1e-12 L^3 catches coplanar and coincident
// nodes robustly. A regular tetrahedron of side h has |6 V| = h^3 / sqrt 2, so the rule rejects
// well-shaped elements only below ~1e-4 L across: ~20 times finer than a uniform mesh of 1e8
// elements, more than an explicit run could afford (its stable step scales with element size).
constexpr double kDegenerateVolumeFraction = 1e-12;

// The faces of a positively oriented tetrahedron (0, 1, 2, 3), face k opposite node k, each
// ordered so that (b - a) x (c - a) points away from node k, i.e. out of the tetrahedron.
// (Each is an odd permutation of the tetrahedron with the opposite node last.)
constexpr int kOutwardFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

// 6 x the signed volume of tetrahedron (a, b, c, d): det [b - a, c - a, d - a], positive when
// (b - a) x (c - a) points towards d.
double six_signed_volume(const Mesh& mesh, int32_t a, int32_t b, int32_t c, int32_t d) {
  const double bx = mesh.x[b] - mesh.x[a], by = mesh.y[b] - mesh.y[a], bz = mesh.z[b] - mesh.z[a];
  const double cx = mesh.x[c] - mesh.x[a], cy = mesh.y[c] - mesh.y[a], cz = mesh.z[c] - mesh.z[a];
  const double dx = mesh.x[d] - mesh.x[a], dy = mesh.y[d] - mesh.y[a], dz = mesh.z[d] - mesh.z[a];
  return bx * (cy * dz - cz * dy) - by * (cx * dz - cz * dx) + bz * (cx * dy - cy * dx);
}

double six_signed_volume(const Mesh& mesh, const std::array<int32_t, 4>& t) {
  return six_signed_volume(mesh, t[0], t[1], t[2], t[3]);
}

[[noreturn]] void reject(const std::string& what) {
  throw std::invalid_argument("finalize_mesh: " + what);
}

std::string describe_tetrahedron(const Mesh& mesh, std::size_t t) {
  const auto& tet = mesh.tetrahedra[t];
  std::ostringstream s;
  s << "tetrahedron " << t << " (nodes " << tet[0] << ", " << tet[1] << ", " << tet[2] << ", "
    << tet[3] << ")";
  return s.str();
}

// Sizes, finite coordinates and index ranges; returns the largest bounding-box side.
double check_nodes_and_indices(const Mesh& mesh) {
  if (mesh.x.size() != mesh.y.size() || mesh.x.size() != mesh.z.size()) {
    reject("x, y and z have " + std::to_string(mesh.x.size()) + ", " +
           std::to_string(mesh.y.size()) + " and " + std::to_string(mesh.z.size()) +
           " coordinates; a 3-D mesh needs as many of each");
  }
  if (mesh.tetrahedra.empty()) {
    reject(mesh.triangles.empty()
               ? "the mesh has no tetrahedra"
               : "the mesh has z coordinates and triangles but no tetrahedra (a 2-D mesh has "
                 "no z; a 3-D mesh has tetrahedra)");
  }
  if (!mesh.triangles.empty()) {
    reject("the mesh has both triangles and tetrahedra; a mesh is 2-D or 3-D");
  }
  // Node indices are int32_t, so larger node counts cannot be addressed.
  if (mesh.x.size() > static_cast<std::size_t>(std::numeric_limits<int32_t>::max())) {
    reject("too many nodes for 32-bit indices (" + std::to_string(mesh.x.size()) + ")");
  }
  std::array<double, 3> lo{}, hi{};
  lo.fill(std::numeric_limits<double>::infinity());
  hi.fill(-std::numeric_limits<double>::infinity());
  for (std::size_t i = 0; i < mesh.x.size(); ++i) {
    const std::array<double, 3> p{mesh.x[i], mesh.y[i], mesh.z[i]};
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(p[k]))
        reject("node " + std::to_string(i) + " has a non-finite coordinate");
      lo[k] = std::min(lo[k], p[k]);
      hi[k] = std::max(hi[k], p[k]);
    }
  }
  const auto node_count = static_cast<int32_t>(mesh.x.size());
  for (std::size_t t = 0; t < mesh.tetrahedra.size(); ++t) {
    for (const int32_t n : mesh.tetrahedra[t]) {
      if (n < 0 || n >= node_count) {
        reject(describe_tetrahedron(mesh, t) + " has node index " + std::to_string(n) +
               " out of range [0, " + std::to_string(node_count) + ")");
      }
    }
  }
  return std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
}

// Flips negatively oriented tetrahedra (swapping their last two nodes); throws on degenerate
// ones.
void orient_positively(Mesh& mesh, double mesh_scale) {
  const double min_six_volume = kDegenerateVolumeFraction * mesh_scale * mesh_scale * mesh_scale;
  for (std::size_t t = 0; t < mesh.tetrahedra.size(); ++t) {
    auto& tet = mesh.tetrahedra[t];
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) {
        if (tet[i] == tet[j])
          reject("degenerate " + describe_tetrahedron(mesh, t) + ": a node is repeated");
      }
    }
    const double v6 = six_signed_volume(mesh, tet);
    if (!(std::abs(v6) > min_six_volume)) {
      std::ostringstream s;
      s << "degenerate " << describe_tetrahedron(mesh, t) << ": volume " << std::abs(v6) / 6.0
        << " (|6 V| = " << std::abs(v6) << ") is below " << kDegenerateVolumeFraction
        << " of the cubed mesh size " << mesh_scale;
      reject(s.str());
    }
    if (v6 < 0.0) std::swap(tet[2], tet[3]);
  }
}

// Whether sorting (a, b, c) takes an odd number of swaps: two uses of one face with different
// parities traverse it in opposite senses.
bool odd_permutation(int32_t a, int32_t b, int32_t c) {
  const int inversions = (a > b) + (a > c) + (b > c);
  return inversions % 2 == 1;
}

// Faces used by exactly one tetrahedron, ordered by (tetrahedron, local face) and oriented
// outwards. Checks that interior faces join exactly two tetrahedra lying on opposite sides.
std::vector<std::array<int32_t, 3>> find_boundary_faces(const Mesh& mesh) {
  struct FaceUse {
    std::array<int32_t, 3> key;  // nodes ascending, for sorting
    uint32_t element;            // tetrahedron
    uint8_t local;               // face k: opposite node k
    bool odd;                    // outward order is an odd permutation of key
  };
  std::vector<FaceUse> uses;
  uses.reserve(4 * mesh.tetrahedra.size());
  for (std::size_t t = 0; t < mesh.tetrahedra.size(); ++t) {
    const auto& tet = mesh.tetrahedra[t];
    for (int k = 0; k < 4; ++k) {
      const int32_t a = tet[kOutwardFace[k][0]], b = tet[kOutwardFace[k][1]],
                    c = tet[kOutwardFace[k][2]];
      std::array<int32_t, 3> key{a, b, c};
      std::sort(key.begin(), key.end());
      uses.push_back(
          {key, static_cast<uint32_t>(t), static_cast<uint8_t>(k), odd_permutation(a, b, c)});
    }
  }
  // Sorting (rather than hashing) keeps every message and the boundary independent of the
  // library.
  std::sort(uses.begin(), uses.end(), [](const FaceUse& l, const FaceUse& r) {
    return l.key != r.key ? l.key < r.key
                          : std::pair(l.element, l.local) < std::pair(r.element, r.local);
  });

  std::vector<uint64_t> boundary_uses;  // 4 * element + local face
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i + 1;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    const std::size_t count = j - i;
    const auto& key = uses[i].key;
    const std::string face_name = "face (" + std::to_string(key[0]) + ", " +
                                  std::to_string(key[1]) + ", " + std::to_string(key[2]) + ")";
    if (count == 1) {
      boundary_uses.push_back(4 * uint64_t{uses[i].element} + uses[i].local);
    } else if (count == 2) {
      // Two positively oriented neighbours see their shared face outward in opposite senses;
      // the same sense means both lie on one side of it, i.e. they overlap.
      if (uses[i].odd == uses[i + 1].odd) {
        reject("tetrahedra " + std::to_string(uses[i].element) + " and " +
               std::to_string(uses[i + 1].element) + " overlap: both lie on the same side of " +
               face_name);
      }
    } else {
      reject(face_name + " is shared by more than two tetrahedra (" + std::to_string(count) +
             ", e.g. tetrahedra " + std::to_string(uses[i].element) + ", " +
             std::to_string(uses[i + 1].element) + ", " + std::to_string(uses[i + 2].element) +
             ")");
    }
    i = j;
  }
  std::sort(boundary_uses.begin(), boundary_uses.end());
  std::vector<std::array<int32_t, 3>> faces;
  faces.reserve(boundary_uses.size());
  for (const uint64_t use : boundary_uses) {
    const auto& tet = mesh.tetrahedra[use / 4];
    const int* local = kOutwardFace[use % 4];
    faces.push_back({tet[local[0]], tet[local[1]], tet[local[2]]});
  }
  return faces;
}

void check_all_nodes_used(const Mesh& mesh) {
  std::vector<char> used(mesh.x.size(), 0);
  for (const auto& tet : mesh.tetrahedra) {
    for (const int32_t n : tet) used[n] = 1;
  }
  const auto unused = std::find(used.begin(), used.end(), 0);
  if (unused != used.end()) {
    const auto count = std::count(used.begin(), used.end(), 0);
    reject("node " + std::to_string(unused - used.begin()) + " is not used by any tetrahedron (" +
           std::to_string(count) + " unused node(s))");
  }
}

// Spreads the low 21 bits of v three apart (bit i goes to bit 3 i).
uint64_t spread_by_three(uint64_t v) {
  v &= 0x1FFFFF;
  v = (v | (v << 32)) & 0x001F00000000FFFFULL;
  v = (v | (v << 16)) & 0x001F0000FF0000FFULL;
  v = (v | (v << 8)) & 0x100F00F00F00F00FULL;
  v = (v | (v << 4)) & 0x10C30C30C30C30C3ULL;
  v = (v | (v << 2)) & 0x1249249249249249ULL;
  return v;
}

}  // namespace

void finalize_tet_mesh(Mesh& mesh) {
  const double mesh_scale = check_nodes_and_indices(mesh);
  orient_positively(mesh, mesh_scale);
  std::vector<std::array<int32_t, 3>> faces = find_boundary_faces(mesh);
  check_all_nodes_used(mesh);
  // A closed volume has a boundary; none means the faces pair up into something with no
  // outside (impossible for a finite set of positive tetrahedra that do not overlap).
  if (faces.empty()) reject("the tetrahedra have no boundary faces");
  mesh.boundary_faces = std::move(faces);
  mesh.boundary_edges.clear();  // 2-D only
  mesh.boundary_nodes.clear();
}

void sort_tet_mesh_for_locality(Mesh& mesh) {
  const std::size_t nn = mesh.node_count(), ne = mesh.tetrahedra.size();
  if (nn == 0 && ne == 0) return;
  // What the keys below rely on; where it fails, finalize names the problem (and throws).
  const auto in_range = [nn](int32_t n) { return n >= 0 && static_cast<std::size_t>(n) < nn; };
  const auto finite = [](double v) { return std::isfinite(v); };
  if (mesh.y.size() != nn || mesh.z.size() != nn || !mesh.triangles.empty() ||
      !std::all_of(mesh.x.begin(), mesh.x.end(), finite) ||
      !std::all_of(mesh.y.begin(), mesh.y.end(), finite) ||
      !std::all_of(mesh.z.begin(), mesh.z.end(), finite) ||
      !std::all_of(mesh.tetrahedra.begin(), mesh.tetrahedra.end(),
                   [&](const auto& t) { return std::all_of(t.begin(), t.end(), in_range); })) {
    finalize_tet_mesh(mesh);
  }
  const auto [xmin, xmax] = std::minmax_element(mesh.x.begin(), mesh.x.end());
  const auto [ymin, ymax] = std::minmax_element(mesh.y.begin(), mesh.y.end());
  const auto [zmin, zmax] = std::minmax_element(mesh.z.begin(), mesh.z.end());
  const double x0 = *xmin, y0 = *ymin, z0 = *zmin;
  const double span = std::max({*xmax - x0, *ymax - y0, *zmax - z0});
  // 21 bits per axis fill a 64-bit key.
  const double scale = span > 0 ? 2097151.0 / span : 0.0;
  auto key = [&](double x, double y, double z) {
    return spread_by_three(static_cast<uint64_t>((x - x0) * scale)) |
           (spread_by_three(static_cast<uint64_t>((y - y0) * scale)) << 1) |
           (spread_by_three(static_cast<uint64_t>((z - z0) * scale)) << 2);
  };
  std::vector<int32_t> order(nn);
  std::iota(order.begin(), order.end(), 0);
  std::vector<uint64_t> node_key(nn);
  for (std::size_t i = 0; i < nn; ++i) node_key[i] = key(mesh.x[i], mesh.y[i], mesh.z[i]);
  std::stable_sort(order.begin(), order.end(),
                   [&](int32_t a, int32_t b) { return node_key[a] < node_key[b]; });
  std::vector<int32_t> new_index(nn);
  Mesh sorted;
  sorted.x.resize(nn), sorted.y.resize(nn), sorted.z.resize(nn);
  for (std::size_t k = 0; k < nn; ++k) {
    new_index[order[k]] = static_cast<int32_t>(k);
    sorted.x[k] = mesh.x[order[k]], sorted.y[k] = mesh.y[order[k]], sorted.z[k] = mesh.z[order[k]];
  }
  std::vector<int32_t> element_order(ne);
  std::iota(element_order.begin(), element_order.end(), 0);
  std::vector<uint64_t> element_key(ne, 0);
  for (std::size_t e = 0; e < ne; ++e) {
    const auto& t = mesh.tetrahedra[e];
    element_key[e] = key((mesh.x[t[0]] + mesh.x[t[1]] + mesh.x[t[2]] + mesh.x[t[3]]) / 4.0,
                         (mesh.y[t[0]] + mesh.y[t[1]] + mesh.y[t[2]] + mesh.y[t[3]]) / 4.0,
                         (mesh.z[t[0]] + mesh.z[t[1]] + mesh.z[t[2]] + mesh.z[t[3]]) / 4.0);
  }
  std::stable_sort(element_order.begin(), element_order.end(),
                   [&](int32_t a, int32_t b) { return element_key[a] < element_key[b]; });
  sorted.tetrahedra.resize(ne);
  for (std::size_t k = 0; k < ne; ++k) {
    const auto& t = mesh.tetrahedra[element_order[k]];
    sorted.tetrahedra[k] = {new_index[t[0]], new_index[t[1]], new_index[t[2]], new_index[t[3]]};
  }
  finalize_tet_mesh(sorted);
  mesh = std::move(sorted);
}

Mesh make_box_mesh(double lx, double ly, double lz, int nx, int ny, int nz) {
  if (!(lx > 0.0) || !(ly > 0.0) || !(lz > 0.0) || !std::isfinite(lx) || !std::isfinite(ly) ||
      !std::isfinite(lz)) {
    throw std::invalid_argument("make_box_mesh: side lengths must be positive and finite");
  }
  if (nx < 1 || ny < 1 || nz < 1) {
    throw std::invalid_argument("make_box_mesh: nx, ny and nz must be at least 1");
  }
  const int64_t columns = int64_t{nx} + 1, rows = int64_t{ny} + 1;
  // Checked factor by factor: the product of three ints can overflow int64_t's checks too.
  const int64_t limit = std::numeric_limits<int32_t>::max();
  if (columns * rows > limit || columns * rows * (int64_t{nz} + 1) > limit) {
    throw std::invalid_argument("make_box_mesh: too many nodes for 32-bit indices");
  }
  const int64_t node_count = columns * rows * (int64_t{nz} + 1);
  Mesh mesh;
  mesh.x.reserve(node_count);
  mesh.y.reserve(node_count);
  mesh.z.reserve(node_count);
  for (int k = 0; k <= nz; ++k) {
    for (int j = 0; j <= ny; ++j) {
      for (int i = 0; i <= nx; ++i) {
        // i * lx / nx rather than i * (lx / nx) puts the last layer exactly at lx.
        mesh.x.push_back(i * lx / nx);
        mesh.y.push_back(j * ly / ny);
        mesh.z.push_back(k * lz / nz);
      }
    }
  }
  auto node = [&](int i, int j, int k) {
    return static_cast<int32_t>((k * rows + j) * columns + i);
  };
  // Kuhn's subdivision: one tetrahedron per path from one corner of the cell to the opposite one
  // along its edges, one per order of the three axes. Cells are mirrored in each axis where
  // their index is odd (the path starts at the far side in that axis): a mirrored neighbour
  // splits the shared face along the same diagonal, so the mesh is conforming, and it is
  // symmetric under reflection about every cell plane -- a box of an even number of cells in x
  // is its own mirror image about x = lx / 2 (one diagonal for all cells gave the box a handedness
  // that moved the two ends of a flat free surface apart by 0.2 um under a 0.2 GPa shock,
  // as large as the Richtmyer-Meshkov signal it was to measure).
  constexpr int kAxisOrders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                     {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  mesh.tetrahedra.reserve(6 * static_cast<std::size_t>(nx) * ny * nz);
  for (int k = 0; k < nz; ++k) {
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        const std::array<int, 3> mirror{i % 2, j % 2, k % 2};
        const bool flipped = (mirror[0] + mirror[1] + mirror[2]) % 2 == 1;
        for (const auto& axes : kAxisOrders) {
          std::array<int, 3> at{i + mirror[0], j + mirror[1], k + mirror[2]};
          std::array<int32_t, 4> tet{};
          tet[0] = node(at[0], at[1], at[2]);
          for (int step = 0; step < 3; ++step) {
            at[axes[step]] += mirror[axes[step]] ? -1 : 1;
            tet[step + 1] = node(at[0], at[1], at[2]);
          }
          // The path's volume has the sign of the axis order's permutation, flipped once per
          // mirrored axis: make it positive here (finalize would, too) so the structured
          // numbering is the final one.
          if (odd_permutation(axes[0], axes[1], axes[2]) != flipped) std::swap(tet[2], tet[3]);
          mesh.tetrahedra.push_back(tet);
        }
      }
    }
  }
  finalize_tet_mesh(mesh);
  return mesh;
}

Mesh make_corrugated_box_mesh(double lx, double ly, double lz, double amplitude, double kx,
                              double ky, int target_elements) {
  if (!(lx > 0.0) || !(ly > 0.0) || !(lz > 0.0) || !std::isfinite(lx) || !std::isfinite(ly) ||
      !std::isfinite(lz) || !std::isfinite(kx) || !std::isfinite(ky) ||
      !(std::fabs(amplitude) < 0.5 * lz)) {
    throw std::invalid_argument(
        "make_corrugated_box_mesh: lx, ly and lz must be positive and finite, kx and ky finite "
        "and |amplitude| < lz / 2");
  }
  if (target_elements < 1) {
    throw std::invalid_argument("make_corrugated_box_mesh: target_elements must be >= 1, got " +
                                std::to_string(target_elements));
  }
  // 6 nx ny nz = N with cubic cells of side h: h^3 = 6 lx ly lz / N. nz takes up the rounding
  // of nx and ny so the count stays near the target.
  const double h = std::cbrt(6.0 * lx * ly * lz / target_elements);
  // Even counts in x and y: the mirrored cells then make the box symmetric about its middle
  // planes, as the corrugation's quarter cell is (the crest and trough columns alike).
  const int nx = std::max(2, 2 * static_cast<int>(std::lround(0.5 * lx / h)));
  const int ny = std::max(2, 2 * static_cast<int>(std::lround(0.5 * ly / h)));
  const int nz = std::max(1, static_cast<int>(std::lround(target_elements / (6.0 * nx * ny))));
  Mesh mesh = make_box_mesh(lx, ly, lz, nx, ny, nz);
  for (std::size_t i = 0; i < mesh.node_count(); ++i) {
    mesh.z[i] *= (lz + amplitude * std::cos(kx * mesh.x[i]) * std::cos(ky * mesh.y[i])) / lz;
  }
  // No tetrahedron turns over, however steep the corrugation: each Kuhn tetrahedron is a path
  // of one x, one y and one z step, and stretching columns keeps the z step vertical (both its
  // nodes share a column) and the x and y steps' horizontal parts, so 6 V = hx hy (stretched
  // hz) > 0 (the shear the stretch adds drops out of the triangular determinant).
  // Morton order, as the Gmsh meshes: the structured numbering puts z-neighbours nx ny nodes
  // apart, which the solver's gathers feel on large meshes. Finalizes too.
  sort_tet_mesh_for_locality(mesh);
  return mesh;
}

Mesh extrude_mesh(const Mesh& base, double z_bottom, double z_top, int layers) {
  if (base.dimension() != 2 || base.triangles.empty())
    throw std::invalid_argument("extrude_mesh: the base must be a 2-D triangle mesh");
  if (layers < 1) throw std::invalid_argument("extrude_mesh: layers must be >= 1");
  if (!(z_top > z_bottom) || !std::isfinite(z_bottom) || !std::isfinite(z_top))
    throw std::invalid_argument("extrude_mesh: needs finite z_bottom < z_top");
  const std::size_t n = base.node_count();
  if ((layers + 1.0) * static_cast<double>(n) > static_cast<double>(INT32_MAX))
    throw std::invalid_argument("extrude_mesh: too many nodes for 32-bit indices");
  Mesh mesh;
  for (int k = 0; k <= layers; ++k) {
    const double z = k == layers ? z_top : z_bottom + (z_top - z_bottom) * k / layers;
    mesh.x.insert(mesh.x.end(), base.x.begin(), base.x.end());
    mesh.y.insert(mesh.y.end(), base.y.begin(), base.y.end());
    mesh.z.insert(mesh.z.end(), n, z);
  }
  mesh.tetrahedra.reserve(3 * base.triangles.size() * static_cast<std::size_t>(layers));
  for (int k = 0; k < layers; ++k) {
    const auto below = static_cast<int32_t>(k * n), above = static_cast<int32_t>((k + 1) * n);
    for (auto t : base.triangles) {
      std::sort(t.begin(), t.end());
      const int32_t a = t[0], b = t[1], c = t[2];
      mesh.tetrahedra.push_back({below + a, below + b, below + c, above + a});
      mesh.tetrahedra.push_back({below + b, below + c, above + a, above + b});
      mesh.tetrahedra.push_back({below + c, above + a, above + b, above + c});
    }
  }
  finalize_mesh(mesh);  // orients each tetrahedron, finds the outward faces
  return mesh;
}

std::array<double, 3> tet_mesh_centroid(const Mesh& mesh) {
  double volume = 0.0;
  std::array<double, 3> first_moment{0.0, 0.0, 0.0};
  for (const auto& t : mesh.tetrahedra) {
    const double v = std::abs(six_signed_volume(mesh, t)) / 6.0;
    volume += v;
    first_moment[0] += v * (mesh.x[t[0]] + mesh.x[t[1]] + mesh.x[t[2]] + mesh.x[t[3]]) / 4.0;
    first_moment[1] += v * (mesh.y[t[0]] + mesh.y[t[1]] + mesh.y[t[2]] + mesh.y[t[3]]) / 4.0;
    first_moment[2] += v * (mesh.z[t[0]] + mesh.z[t[1]] + mesh.z[t[2]] + mesh.z[t[3]]) / 4.0;
  }
  if (!(volume > 0.0)) throw std::invalid_argument("tet_mesh_centroid: the mesh has zero volume");
  return {first_moment[0] / volume, first_moment[1] / volume, first_moment[2] / volume};
}

double mesh_volume(const Mesh& mesh) {
  double volume = 0.0;
  for (const auto& t : mesh.tetrahedra) volume += std::abs(six_signed_volume(mesh, t)) / 6.0;
  return volume;
}

}  // namespace softshock
