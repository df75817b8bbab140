// Mesh checks, orientation and boundary extraction; structured rectangle meshes.
#include "solver/mesh.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace softshock {
namespace {

// A triangle counts as degenerate when its area is below this fraction of L^2, L being the
// larger side of the mesh's bounding box. Rounding in the cross product of a collinear triple
// is ~1e-16 L^2, so 1e-12 L^2 catches collinear and coincident nodes robustly, yet it only
// rejects elements ~1e-6 L across or smaller, far below anything an explicit run could afford
// (its stable time step scales with element size).
constexpr double kDegenerateAreaFraction = 1e-12;

// Twice the signed area of triangle (a, b, c): positive when counter-clockwise.
double twice_signed_area(const Mesh& mesh, int32_t a, int32_t b, int32_t c) {
  const double abx = mesh.x[b] - mesh.x[a], aby = mesh.y[b] - mesh.y[a];
  const double acx = mesh.x[c] - mesh.x[a], acy = mesh.y[c] - mesh.y[a];
  return abx * acy - acx * aby;
}

[[noreturn]] void reject(const std::string& what) {
  throw std::invalid_argument("finalize_mesh: " + what);
}

std::string describe_triangle(const Mesh& mesh, std::size_t t) {
  const auto& tri = mesh.triangles[t];
  std::ostringstream s;
  s << "triangle " << t << " (nodes " << tri[0] << ", " << tri[1] << ", " << tri[2] << ")";
  return s.str();
}

// Sizes, finite coordinates and index ranges; returns the larger bounding-box side.
double check_nodes_and_indices(const Mesh& mesh) {
  if (mesh.x.size() != mesh.y.size()) {
    reject("x has " + std::to_string(mesh.x.size()) + " coordinates but y has " +
           std::to_string(mesh.y.size()));
  }
  if (mesh.triangles.empty()) reject("the mesh has no triangles");
  // Node indices are int32_t, so larger node counts cannot be addressed.
  if (mesh.x.size() > static_cast<std::size_t>(std::numeric_limits<int32_t>::max())) {
    reject("too many nodes for 32-bit indices (" + std::to_string(mesh.x.size()) + ")");
  }
  double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin;
  double ymin = xmin, ymax = -xmin;
  for (std::size_t i = 0; i < mesh.x.size(); ++i) {
    if (!std::isfinite(mesh.x[i]) || !std::isfinite(mesh.y[i])) {
      reject("node " + std::to_string(i) + " has a non-finite coordinate");
    }
    xmin = std::min(xmin, mesh.x[i]);
    xmax = std::max(xmax, mesh.x[i]);
    ymin = std::min(ymin, mesh.y[i]);
    ymax = std::max(ymax, mesh.y[i]);
  }
  const auto node_count = static_cast<int32_t>(mesh.x.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (const int32_t n : mesh.triangles[t]) {
      if (n < 0 || n >= node_count) {
        reject(describe_triangle(mesh, t) + " has node index " + std::to_string(n) +
               " out of range [0, " + std::to_string(node_count) + ")");
      }
    }
  }
  return std::max(xmax - xmin, ymax - ymin);
}

// Flips clockwise triangles; throws on degenerate ones.
void orient_counter_clockwise(Mesh& mesh, double mesh_scale) {
  const double min_twice_area = 2.0 * kDegenerateAreaFraction * mesh_scale * mesh_scale;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    auto& tri = mesh.triangles[t];
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
      reject("degenerate " + describe_triangle(mesh, t) + ": a node is repeated");
    }
    const double a2 = twice_signed_area(mesh, tri[0], tri[1], tri[2]);
    if (!(std::abs(a2) > min_twice_area)) {
      std::ostringstream s;
      s << "degenerate " << describe_triangle(mesh, t) << ": area " << 0.5 * std::abs(a2)
        << " is below " << kDegenerateAreaFraction << " of the squared mesh size " << mesh_scale;
      reject(s.str());
    }
    if (a2 < 0.0) std::swap(tri[1], tri[2]);
  }
}

struct DirectedEdge {
  int32_t from, to;
};

// Edges used by exactly one triangle, directed as in that (counter-clockwise) triangle so the
// body lies on their left. Checks that interior edges join exactly two triangles that lie on
// opposite sides of them.
std::vector<DirectedEdge> find_boundary_edges(const Mesh& mesh) {
  struct EdgeUse {
    uint64_t key;  // (min node, max node) packed, for sorting
    int32_t from, to;
    uint32_t triangle;
  };
  std::vector<EdgeUse> uses;
  uses.reserve(3 * mesh.triangles.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    for (int k = 0; k < 3; ++k) {
      const int32_t a = tri[k], b = tri[(k + 1) % 3];
      const auto lo = static_cast<uint64_t>(std::min(a, b));
      const auto hi = static_cast<uint64_t>(std::max(a, b));
      uses.push_back({(lo << 32) | hi, a, b, static_cast<uint32_t>(t)});
    }
  }
  // Sorting (rather than hashing) keeps the boundary order independent of the library.
  std::sort(uses.begin(), uses.end(), [](const EdgeUse& l, const EdgeUse& r) {
    return l.key != r.key ? l.key < r.key : l.triangle < r.triangle;
  });

  std::vector<DirectedEdge> boundary;
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i + 1;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    const std::size_t count = j - i;
    const std::string edge_name =
        "edge (" + std::to_string(uses[i].from) + ", " + std::to_string(uses[i].to) + ")";
    if (count == 1) {
      boundary.push_back({uses[i].from, uses[i].to});
    } else if (count == 2) {
      // Two counter-clockwise neighbours traverse their shared edge in opposite directions;
      // the same direction means both lie on one side of it, i.e. they overlap.
      if (uses[i].from == uses[i + 1].from) {
        reject("triangles " + std::to_string(uses[i].triangle) + " and " +
               std::to_string(uses[i + 1].triangle) + " overlap: both lie on the same side of " +
               edge_name);
      }
    } else {
      reject(edge_name + " is shared by more than two triangles (" + std::to_string(count) +
             ", e.g. triangles " + std::to_string(uses[i].triangle) + ", " +
             std::to_string(uses[i + 1].triangle) + ", " + std::to_string(uses[i + 2].triangle) +
             ")");
    }
    i = j;
  }
  return boundary;
}

void check_all_nodes_used(const Mesh& mesh) {
  std::vector<char> used(mesh.x.size(), 0);
  for (const auto& tri : mesh.triangles) {
    for (const int32_t n : tri) used[n] = 1;
  }
  const auto unused = std::find(used.begin(), used.end(), 0);
  if (unused != used.end()) {
    const auto count = std::count(used.begin(), used.end(), 0);
    reject("node " + std::to_string(unused - used.begin()) + " is not used by any triangle (" +
           std::to_string(count) + " unused node(s))");
  }
}

// Chains the boundary edges into closed loops. Each edge's successor is an edge leaving its end
// node; where several leave it (two parts of the body touching at one node) the successor is
// the one bounding the same wedge of body as the incoming edge: the first outgoing edge met
// turning clockwise from the direction back along the incoming edge. This keeps every loop
// from crossing itself.
std::vector<std::vector<int32_t>> chain_loops(const Mesh& mesh,
                                              const std::vector<DirectedEdge>& edges) {
  std::vector<std::size_t> sorted(edges.size());
  for (std::size_t e = 0; e < edges.size(); ++e) sorted[e] = e;
  std::sort(sorted.begin(), sorted.end(), [&](std::size_t l, std::size_t r) {
    return std::pair(edges[l].from, edges[l].to) < std::pair(edges[r].from, edges[r].to);
  });
  // first_out[n] .. first_out[n + 1]: positions in `sorted` of the edges leaving node n.
  std::vector<std::size_t> first_out(mesh.x.size() + 1, 0);
  for (const auto& e : edges) ++first_out[e.from + 1];
  for (std::size_t n = 0; n < mesh.x.size(); ++n) first_out[n + 1] += first_out[n];

  auto successor = [&](std::size_t e) -> std::size_t {
    const int32_t v = edges[e].to;
    const std::size_t begin = first_out[v], end = first_out[v + 1];
    if (end - begin == 1) return sorted[begin];
    if (end == begin) {
      // Every node has as many boundary edges arriving as leaving; this means inconsistent input.
      reject("boundary edge (" + std::to_string(edges[e].from) + ", " + std::to_string(v) +
             ") has no continuation");
    }
    const double back =
        std::atan2(mesh.y[edges[e].from] - mesh.y[v], mesh.x[edges[e].from] - mesh.x[v]);
    std::size_t best = sorted[begin];
    double best_turn = std::numeric_limits<double>::infinity();
    for (std::size_t k = begin; k < end; ++k) {
      const auto& out = edges[sorted[k]];
      const double dir = std::atan2(mesh.y[out.to] - mesh.y[v], mesh.x[out.to] - mesh.x[v]);
      double clockwise_turn = back - dir;  // in (-2 pi, 2 pi); brought into (0, 2 pi]
      if (clockwise_turn <= 0.0) clockwise_turn += 2.0 * std::numbers::pi;
      if (clockwise_turn < best_turn) {
        best_turn = clockwise_turn;
        best = sorted[k];
      }
    }
    return best;
  };

  std::vector<std::vector<int32_t>> loops;
  std::vector<char> used(edges.size(), 0);
  for (const std::size_t start : sorted) {
    if (used[start]) continue;
    std::vector<int32_t> loop;
    std::size_t e = start;
    do {
      if (used[e]) {
        reject("boundary edges do not form closed loops near node " +
               std::to_string(edges[e].from));
      }
      used[e] = 1;
      loop.push_back(edges[e].from);
      e = successor(e);
    } while (e != start);
    loops.push_back(std::move(loop));
  }
  return loops;
}

double loop_signed_area(const Mesh& mesh, const std::vector<int32_t>& loop) {
  // Shoelace formula about the first node, which limits cancellation for small loops far from
  // the origin.
  const double x0 = mesh.x[loop[0]], y0 = mesh.y[loop[0]];
  double twice_area = 0.0;
  for (std::size_t i = 1; i + 1 < loop.size(); ++i) {
    twice_area += (mesh.x[loop[i]] - x0) * (mesh.y[loop[i + 1]] - y0) -
                  (mesh.x[loop[i + 1]] - x0) * (mesh.y[loop[i]] - y0);
  }
  return 0.5 * twice_area;
}

}  // namespace

void finalize_mesh(Mesh& mesh) {
  if (mesh.dimension() == 3) {  // tetrahedra: tet_mesh.cpp
    finalize_tet_mesh(mesh);
    return;
  }
  const double mesh_scale = check_nodes_and_indices(mesh);
  orient_counter_clockwise(mesh, mesh_scale);
  const std::vector<DirectedEdge> edges = find_boundary_edges(mesh);
  check_all_nodes_used(mesh);
  std::vector<std::vector<int32_t>> loops = chain_loops(mesh, edges);

  // The outer loop encloses the largest area; a hole's loop runs clockwise (body on the left),
  // so compare magnitudes. Ties keep the first loop found, which is deterministic.
  std::size_t outer = 0;
  double outer_area = -1.0;
  for (std::size_t l = 0; l < loops.size(); ++l) {
    const double area = std::abs(loop_signed_area(mesh, loops[l]));
    if (area > outer_area) {
      outer_area = area;
      outer = l;
    }
  }
  // Start every loop at its smallest node index so the result does not depend on input order
  // beyond the numbering.
  for (auto& loop : loops) {
    std::rotate(loop.begin(), std::min_element(loop.begin(), loop.end()), loop.end());
  }
  if (loop_signed_area(mesh, loops[outer]) < 0.0) {
    // Cannot happen for a planar mesh whose triangles do not overlap: the loop around the body
    // with the body on its left runs counter-clockwise.
    reject("the outer boundary loop runs clockwise; triangles overlap or the mesh folds");
  }

  // Boundary edges in loop order, outer loop first, so consumers can walk them.
  mesh.boundary_edges.clear();
  mesh.boundary_edges.reserve(edges.size());
  auto append_loop = [&](const std::vector<int32_t>& loop) {
    for (std::size_t i = 0; i < loop.size(); ++i) {
      mesh.boundary_edges.push_back({loop[i], loop[(i + 1) % loop.size()]});
    }
  };
  append_loop(loops[outer]);
  for (std::size_t l = 0; l < loops.size(); ++l) {
    if (l != outer) append_loop(loops[l]);
  }
  mesh.boundary_nodes = std::move(loops[outer]);
}

namespace {

// Interleaves the low 16 bits of i and j (Morton code).
uint32_t interleave(uint32_t i, uint32_t j) {
  auto spread = [](uint32_t v) {
    v &= 0xFFFF;
    v = (v | (v << 8)) & 0x00FF00FF;
    v = (v | (v << 4)) & 0x0F0F0F0F;
    v = (v | (v << 2)) & 0x33333333;
    v = (v | (v << 1)) & 0x55555555;
    return v;
  };
  return spread(i) | (spread(j) << 1);
}

}  // namespace

void sort_for_locality(Mesh& mesh) {
  if (mesh.dimension() == 3) {  // tetrahedra: tet_mesh.cpp
    sort_tet_mesh_for_locality(mesh);
    return;
  }
  const std::size_t nn = mesh.node_count(), ne = mesh.element_count();
  if (nn == 0) return;
  const auto [xmin, xmax] = std::minmax_element(mesh.x.begin(), mesh.x.end());
  const auto [ymin, ymax] = std::minmax_element(mesh.y.begin(), mesh.y.end());
  const double x0 = *xmin, y0 = *ymin;
  const double span = std::max(*xmax - x0, *ymax - y0);
  const double scale = span > 0 ? 65535.0 / span : 0.0;
  auto key = [&](double x, double y) {
    return interleave(static_cast<uint32_t>((x - x0) * scale),
                      static_cast<uint32_t>((y - y0) * scale));
  };
  std::vector<int32_t> order(nn);
  std::iota(order.begin(), order.end(), 0);
  std::vector<uint32_t> node_key(nn);
  for (std::size_t i = 0; i < nn; ++i) node_key[i] = key(mesh.x[i], mesh.y[i]);
  std::stable_sort(order.begin(), order.end(),
                   [&](int32_t a, int32_t b) { return node_key[a] < node_key[b]; });
  std::vector<int32_t> new_index(nn);
  Mesh sorted;
  sorted.x.resize(nn), sorted.y.resize(nn);
  for (std::size_t k = 0; k < nn; ++k) {
    new_index[order[k]] = static_cast<int32_t>(k);
    sorted.x[k] = mesh.x[order[k]], sorted.y[k] = mesh.y[order[k]];
  }
  std::vector<int32_t> element_order(ne);
  std::iota(element_order.begin(), element_order.end(), 0);
  std::vector<uint32_t> element_key(ne);
  for (std::size_t e = 0; e < ne; ++e) {
    const auto& t = mesh.triangles[e];
    element_key[e] = key((mesh.x[t[0]] + mesh.x[t[1]] + mesh.x[t[2]]) / 3.0,
                         (mesh.y[t[0]] + mesh.y[t[1]] + mesh.y[t[2]]) / 3.0);
  }
  std::stable_sort(element_order.begin(), element_order.end(),
                   [&](int32_t a, int32_t b) { return element_key[a] < element_key[b]; });
  sorted.triangles.resize(ne);
  for (std::size_t k = 0; k < ne; ++k) {
    const auto& t = mesh.triangles[element_order[k]];
    sorted.triangles[k] = {new_index[t[0]], new_index[t[1]], new_index[t[2]]};
  }
  finalize_mesh(sorted);
  mesh = std::move(sorted);
}

Mesh make_corrugated_strip_mesh(double wavelength, double height, double amplitude,
                                int target_elements) {
  if (!(wavelength > 0.0) || !(height > 0.0) || !std::isfinite(wavelength) ||
      !std::isfinite(height) || !(std::fabs(amplitude) < 0.5 * height)) {
    throw std::invalid_argument(
        "make_corrugated_strip_mesh: wavelength and height must be positive and finite and "
        "|amplitude| < height / 2");
  }
  const double width = 0.5 * wavelength;
  // 2 nx ny = N with square cells: nx = sqrt(N width / (2 height)).
  const int nx =
      std::max(1, static_cast<int>(std::lround(std::sqrt(0.5 * target_elements * width / height))));
  const int ny = std::max(1, static_cast<int>(std::lround(0.5 * target_elements / nx)));
  Mesh mesh = make_rectangle_mesh(width, height, nx, ny);
  const double k = 2.0 * std::numbers::pi / wavelength;
  for (std::size_t i = 0; i < mesh.node_count(); ++i)
    mesh.y[i] *= (height + amplitude * std::cos(k * mesh.x[i])) / height;
  return mesh;
}

void rotate_mesh(Mesh& mesh, double angle_rad) {
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  for (std::size_t i = 0; i < mesh.node_count(); ++i) {
    const double x = mesh.x[i], y = mesh.y[i];
    mesh.x[i] = c * x - s * y, mesh.y[i] = s * x + c * y;
  }
}

Mesh make_rectangle_mesh(double lx, double ly, int nx, int ny) {
  if (!(lx > 0.0) || !(ly > 0.0) || !std::isfinite(lx) || !std::isfinite(ly)) {
    throw std::invalid_argument("make_rectangle_mesh: side lengths must be positive and finite");
  }
  if (nx < 1 || ny < 1) {
    throw std::invalid_argument("make_rectangle_mesh: nx and ny must be at least 1");
  }
  const auto columns = static_cast<int64_t>(nx) + 1;
  const int64_t node_count = columns * (static_cast<int64_t>(ny) + 1);
  if (node_count > std::numeric_limits<int32_t>::max()) {
    throw std::invalid_argument("make_rectangle_mesh: too many nodes for 32-bit indices");
  }
  Mesh mesh;
  mesh.x.reserve(node_count);
  mesh.y.reserve(node_count);
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      // i * lx / nx rather than i * (lx / nx) puts the last column exactly at lx.
      mesh.x.push_back(i * lx / nx);
      mesh.y.push_back(j * ly / ny);
    }
  }
  auto node = [&](int i, int j) { return static_cast<int32_t>(j * columns + i); };
  mesh.triangles.reserve(2 * static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const int32_t sw = node(i, j), se = node(i + 1, j), ne = node(i + 1, j + 1),
                    nw = node(i, j + 1);
      // Checkerboard of diagonals: all-parallel diagonals make a structured mesh stiffer
      // along one direction and bias wave fronts; alternating them removes that preference.
      if ((i + j) % 2 == 0) {
        mesh.triangles.push_back({sw, se, ne});
        mesh.triangles.push_back({sw, ne, nw});
      } else {
        mesh.triangles.push_back({sw, se, nw});
        mesh.triangles.push_back({se, ne, nw});
      }
    }
  }
  finalize_mesh(mesh);
  return mesh;
}

std::array<double, 2> mesh_centroid(const Mesh& mesh) {
  double area = 0.0, first_moment_x = 0.0, first_moment_y = 0.0;
  for (const auto& tri : mesh.triangles) {
    const double a = 0.5 * std::abs(twice_signed_area(mesh, tri[0], tri[1], tri[2]));
    area += a;
    first_moment_x += a * (mesh.x[tri[0]] + mesh.x[tri[1]] + mesh.x[tri[2]]) / 3.0;
    first_moment_y += a * (mesh.y[tri[0]] + mesh.y[tri[1]] + mesh.y[tri[2]]) / 3.0;
  }
  if (!(area > 0.0)) throw std::invalid_argument("mesh_centroid: the mesh has zero area");
  return {first_moment_x / area, first_moment_y / area};
}

double mesh_area(const Mesh& mesh) {
  double area = 0.0;
  for (const auto& tri : mesh.triangles) {
    area += 0.5 * std::abs(twice_signed_area(mesh, tri[0], tri[1], tri[2]));
  }
  return area;
}

}  // namespace softshock
