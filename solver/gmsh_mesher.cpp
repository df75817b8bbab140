// Disk and rounded-square meshes (triangles), cylinder and sphere meshes (tetrahedra), and .msh
// reading, through Gmsh's C++ API (Gmsh 4.8).
//
// Gmsh is a process-wide singleton with global options and a global model, so every use here
// holds one mutex for the whole initialize .. finalize span. Each call starts from a fresh
// initialize, without reading the user's gmshrc, so results depend only on the arguments; and
// a failed call cannot leave state behind (Gmsh 4.8 keeps its "busy" flag set after an error
// while reading a file and then silently ignores later reads until it is re-initialized).
//
// Geometry is built normalised to unit size (unit radius, unit side) and the coordinates are
// scaled to metres afterwards. Gmsh's tolerances are absolute (Geometry.Tolerance = 1e-8,
// OpenCASCADE's 1e-7): on a 90e-6 m disk they would be ~1e-3 of the radius and up to 5 % of
// an element's side, and would change with the physical size. In normalised units they stay
// ~1e-7 of the size and the mesh is the same, up to scale, whatever the physical size.
//
// Side effects of Gmsh worth knowing: initialize sets LC_NUMERIC to "C" for the whole process,
// and the mesher uses the C library's rand().
#include "solver/gmsh_mesher.hpp"

#include <gmsh.h>
#include <stdlib.h>  // mkdtemp

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <unordered_map>
#include <utility>
#include <vector>

#include "solver/msh_counts.hpp"

namespace softshock {
namespace {

constexpr int kGmshTriangle3 = 2;                  // Gmsh element type: 3-node triangle
constexpr int kGmshTetrahedron4 = 4;               // Gmsh element type: 4-node tetrahedron
constexpr int kFrontalDelaunay2D = 6;              // Mesh.Algorithm value
constexpr int kDelaunay3D = 1;                     // Mesh.Algorithm3D value (single-threaded)
constexpr double kCountTolerance = 0.02;           // accept a pass within 2 % of the target count
constexpr int kMaxMeshingPasses = 3;               // first estimate + up to two corrections
constexpr double kMinCornerRadiusFraction = 1e-5;  // of the side; see mesh_rounded_square
// 3-D: the count is noisier in h (it jumps as a thin body gains a layer of elements), so more
// passes are allowed; small meshes need them, and cost little.
constexpr double kTetCountTolerance = 0.03;
constexpr int kMaxTetMeshingPasses = 5;
// Gmsh's 3-D Delaunay mesh of uniform size h has ~0.55 times as many tetrahedra as regular
// tetrahedra of side h (volume h^3 / (6 sqrt 2)) would need to fill the body (its tetrahedra
// are larger on average): measured 0.53-0.60 on cylinders (R = 90 um, H = 20 and 50 um) and
// spheres at 100k-400k elements; more where the boundary weighs (0.66 at 20k, H = 20 um).
constexpr double kDelaunayTetsPerRegularTet = 0.55;
constexpr double kMinThicknessRatio = 1e-5;  // of the radius; see mesh_cylinder

std::mutex& gmsh_mutex() {
  static std::mutex mutex;  // function-local: constructed on first use, no init-order issues
  return mutex;
}

// Turns whatever Gmsh threw into text. Gmsh 4.8 throws std::string on errors
// (General.AbortOnError = 2, set by initialize); other versions may throw std::exception.
std::string describe_current_exception() {
  try {
    throw;
  } catch (const std::string& message) {
    return message;
  } catch (const char* message) {
    return message != nullptr ? message : "unknown Gmsh error";
  } catch (const std::exception& e) {
    return e.what();
  } catch (...) {
    return "unknown Gmsh error";
  }
}

// Holds the Gmsh mutex from initialize to finalize.
class GmshSession {
 public:
  GmshSession() : lock_(gmsh_mutex()) {
    // No argv and no configuration files: a user's ~/.gmshrc must not change our meshes.
    gmsh::initialize(0, nullptr, /*readConfigFiles=*/false);
    try {
      // Errors still arrive as exceptions; Gmsh's chatter must not fill the daemon's stdout.
      gmsh::option::setNumber("General.Terminal", 0);
      // Multithreaded meshing is not reproducible from run to run.
      gmsh::option::setNumber("General.NumThreads", 1);
    } catch (...) {
      gmsh::finalize();
      throw;
    }
  }
  ~GmshSession() {
    try {
      gmsh::finalize();
    } catch (...) {
      // Nothing useful to do; the next session re-initializes from scratch.
    }
  }
  GmshSession(const GmshSession&) = delete;
  GmshSession& operator=(const GmshSession&) = delete;

 private:
  std::lock_guard<std::mutex> lock_;  // first member: locked before initialize, freed after
};

// The elements of one type (3-node triangles or 4-node tetrahedra) of the current Gmsh model
// (all entities), with nodes renumbered 0..N-1 in increasing Gmsh tag order and only the nodes
// the elements use. Coordinates are multiplied by `scale`; z is kept for tetrahedra and dropped
// for triangles. Not finalized.
Mesh extract_elements(int gmsh_type, double scale) {
  const bool tetrahedra = gmsh_type == kGmshTetrahedron4;
  const std::size_t nodes_per_element = tetrahedra ? 4 : 3;
  std::vector<std::size_t> element_tags, element_nodes;
  gmsh::model::mesh::getElementsByType(gmsh_type, element_tags, element_nodes);
  if (element_nodes.size() != nodes_per_element * element_tags.size()) {
    throw std::runtime_error("Gmsh returned " + std::to_string(element_nodes.size()) +
                             " node tags for " + std::to_string(element_tags.size()) + " elements");
  }
  std::vector<std::size_t> node_tags;
  std::vector<double> coords, parametric;
  gmsh::model::mesh::getNodes(node_tags, coords, parametric, -1, -1,
                              /*includeBoundary=*/false, /*returnParametricCoord=*/false);

  std::vector<std::size_t> used(element_nodes);
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  if (used.size() > static_cast<std::size_t>(std::numeric_limits<int32_t>::max())) {
    throw std::runtime_error("too many nodes for 32-bit indices");
  }
  std::unordered_map<std::size_t, std::size_t> position_of_tag;  // into node_tags / coords
  position_of_tag.reserve(node_tags.size());
  for (std::size_t i = 0; i < node_tags.size(); ++i) position_of_tag.emplace(node_tags[i], i);

  Mesh mesh;
  mesh.x.resize(used.size());
  mesh.y.resize(used.size());
  if (tetrahedra) mesh.z.resize(used.size());
  for (std::size_t n = 0; n < used.size(); ++n) {
    const auto found = position_of_tag.find(used[n]);
    if (found == position_of_tag.end()) {
      throw std::runtime_error(std::string(tetrahedra ? "a tetrahedron" : "a triangle") +
                               " refers to node " + std::to_string(used[n]) +
                               ", which has no coordinates");
    }
    mesh.x[n] = coords[3 * found->second] * scale;
    mesh.y[n] = coords[3 * found->second + 1] * scale;
    if (tetrahedra) mesh.z[n] = coords[3 * found->second + 2] * scale;
  }
  auto index_of = [&](std::size_t tag) {
    return static_cast<int32_t>(std::lower_bound(used.begin(), used.end(), tag) - used.begin());
  };
  if (tetrahedra) {
    mesh.tetrahedra.resize(element_tags.size());
    for (std::size_t t = 0; t < element_tags.size(); ++t) {
      for (int k = 0; k < 4; ++k) mesh.tetrahedra[t][k] = index_of(element_nodes[4 * t + k]);
    }
  } else {
    mesh.triangles.resize(element_tags.size());
    for (std::size_t t = 0; t < element_tags.size(); ++t) {
      for (int k = 0; k < 3; ++k) mesh.triangles[t][k] = index_of(element_nodes[3 * t + k]);
    }
  }
  return mesh;
}

std::size_t element_count(int gmsh_type) {
  std::vector<std::size_t> element_tags, element_nodes;
  gmsh::model::mesh::getElementsByType(gmsh_type, element_tags, element_nodes);
  return element_tags.size();
}

// Uniform size: not from the geometry's points, nor refined by curvature (a circle's resolution
// follows from h alone), nor carried in from boundary discretisation.
void set_uniform_size_options() {
  gmsh::option::setNumber("Mesh.MeshSizeFromPoints", 0);
  gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
  gmsh::option::setNumber("Mesh.MeshSizeExtendFromBoundary", 0);
  gmsh::option::setNumber("Mesh.ElementOrder", 1);
}

// Meshes the synchronized 2D model (of the given normalised area) with about target_elements
// triangles and returns the mesh scaled by `scale`.
//
// The first size is the equilateral estimate: N triangles of side h cover N sqrt(3)/4 h^2, so
// h = sqrt(4 A / (sqrt(3) N)). The mesher packs slightly differently from that ideal (boundary
// layer, smoothing), so when the count misses by more than kCountTolerance the size is scaled
// by sqrt(N_got / N_target) (N ~ 1/h^2) and the surface re-meshed; the closest pass wins.
Mesh mesh_to_target_count(double normalised_area, int target_elements, double scale) {
  gmsh::option::setNumber("Mesh.Algorithm", kFrontalDelaunay2D);
  set_uniform_size_options();

  const double target = target_elements;
  double h = std::sqrt(4.0 * normalised_area / (std::sqrt(3.0) * target));
  Mesh best;
  double best_miss = std::numeric_limits<double>::infinity();
  for (int pass = 0; pass < kMaxMeshingPasses; ++pass) {
    gmsh::model::mesh::clear();
    gmsh::option::setNumber("Mesh.MeshSizeMin", h);
    gmsh::option::setNumber("Mesh.MeshSizeMax", h);
    gmsh::model::mesh::generate(2);
    const auto count = static_cast<double>(element_count(kGmshTriangle3));
    if (count == 0.0) throw std::runtime_error("Gmsh produced no triangles");
    const double miss = std::abs(count - target) / target;
    if (miss < best_miss) {
      best = extract_elements(kGmshTriangle3, scale);
      best_miss = miss;
    }
    if (miss <= kCountTolerance) break;
    h *= std::sqrt(count / target);
  }
  return best;
}

// Meshes the synchronized 3-D model (of the given normalised volume) with about
// target_elements tetrahedra and returns the mesh scaled by `scale`.
//
// The first size is the calibrated estimate h^3 = 6 sqrt(2) V kDelaunayTetsPerRegularTet / N.
// A pass that misses by more than kTetCountTolerance is followed by one at a corrected size:
// h scaled by (N_got / N_target)^(1/3) (N ~ 1/h^3) until passes on both sides of the target
// exist, then interpolated between the closest two in log N - log h (the count is not quite a
// power of h when a thin body holds a few layers). The closest pass wins.
Mesh mesh_3d_to_target_count(double normalised_volume, int target_elements, double scale) {
  gmsh::option::setNumber("Mesh.Algorithm", kFrontalDelaunay2D);  // the bounding surfaces
  gmsh::option::setNumber("Mesh.Algorithm3D", kDelaunay3D);
  set_uniform_size_options();

  const double target = target_elements;
  double h = std::cbrt(6.0 * std::numbers::sqrt2 * normalised_volume * kDelaunayTetsPerRegularTet /
                       target);
  struct Pass {
    double h, count;
  };
  std::optional<Pass> too_many, too_few;  // the closest passes on either side of the target
  Mesh best;
  double best_miss = std::numeric_limits<double>::infinity();
  for (int pass = 0; pass < kMaxTetMeshingPasses; ++pass) {
    gmsh::model::mesh::clear();
    gmsh::option::setNumber("Mesh.MeshSizeMin", h);
    gmsh::option::setNumber("Mesh.MeshSizeMax", h);
    gmsh::model::mesh::generate(3);
    const auto count = static_cast<double>(element_count(kGmshTetrahedron4));
    if (count == 0.0) throw std::runtime_error("Gmsh produced no tetrahedra");
    const double miss = std::abs(count - target) / target;
    if (miss < best_miss) {
      best = extract_elements(kGmshTetrahedron4, scale);
      best_miss = miss;
    }
    if (miss <= kTetCountTolerance) break;
    // Larger h means fewer elements: the closest sizes either side are the largest h with too
    // many and the smallest h with too few.
    if (count > target && (!too_many || h > too_many->h)) too_many = Pass{h, count};
    if (count < target && (!too_few || h < too_few->h)) too_few = Pass{h, count};
    if (too_many && too_few) {
      const double f =
          std::log(target / too_many->count) / std::log(too_few->count / too_many->count);
      h = too_many->h * std::pow(too_few->h / too_many->h, f);
    } else {
      h *= std::cbrt(count / target);
    }
  }
  return best;
}

void check_target(const char* function, int target_elements) {
  if (target_elements < 1) {
    throw std::invalid_argument(std::string(function) + ": target_elements must be >= 1, got " +
                                std::to_string(target_elements));
  }
}

// A private directory removed with everything in it when this goes out of scope.
class TemporaryDirectory {
 public:
  TemporaryDirectory() {
    std::string pattern =
        (std::filesystem::temp_directory_path() / "softshock-msh-XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) {
      throw std::system_error(errno, std::generic_category(), "mkdtemp");
    }
    path_ = pattern;
  }
  ~TemporaryDirectory() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
  }
  TemporaryDirectory(const TemporaryDirectory&) = delete;
  TemporaryDirectory& operator=(const TemporaryDirectory&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// Gmsh parses any file that does not look like a mesh as a .geo script, whatever its name, and
// that language can run shell commands (SystemCall). Only MSH files get through.
bool starts_like_msh(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string first_token;
  in >> first_token;
  return first_token == "$MeshFormat";
}

}  // namespace

Mesh mesh_disk(double radius_m, int target_elements) {
  if (!(radius_m > 0.0) || !std::isfinite(radius_m)) {
    throw std::invalid_argument("mesh_disk: radius must be positive and finite");
  }
  check_target("mesh_disk", target_elements);
  Mesh mesh;
  {
    GmshSession session;
    try {
      gmsh::model::add("disk");
      gmsh::model::occ::addDisk(0.0, 0.0, 0.0, 1.0, 1.0);  // unit radius, scaled below
      gmsh::model::occ::synchronize();
      mesh = mesh_to_target_count(std::numbers::pi, target_elements, radius_m);
    } catch (...) {
      throw std::runtime_error("mesh_disk: Gmsh failed: " + describe_current_exception());
    }
  }
  sort_for_locality(mesh);  // finalizes too
  return mesh;
}

Mesh mesh_rounded_square(double side_m, double corner_radius_m, int target_elements) {
  if (!(side_m > 0.0) || !std::isfinite(side_m)) {
    throw std::invalid_argument("mesh_rounded_square: side must be positive and finite");
  }
  // A radius of half the side would leave zero-length straight edges (the disk is mesh_disk).
  if (!(corner_radius_m >= 0.0) || !(corner_radius_m < 0.5 * side_m)) {
    throw std::invalid_argument(
        "mesh_rounded_square: corner radius must be in [0, side / 2), got " +
        std::to_string(corner_radius_m) + " for side " + std::to_string(side_m));
  }
  check_target("mesh_rounded_square", target_elements);
  const double r = corner_radius_m / side_m;  // normalised to unit side
  // Arcs much smaller than OpenCASCADE's tolerance (1e-7 in these unit-side coordinates) fail
  // or collapse into degenerate triangles (seen at 5e-7); 1e-5 keeps a wide margin.
  if (r > 0.0 && r < kMinCornerRadiusFraction) {
    throw std::invalid_argument(
        "mesh_rounded_square: corner radius must be 0 (sharp) or at least 1e-5 of the side, "
        "got " +
        std::to_string(corner_radius_m) + " for side " + std::to_string(side_m));
  }
  Mesh mesh;
  {
    GmshSession session;
    try {
      gmsh::model::add("rounded_square");
      gmsh::model::occ::addRectangle(-0.5, -0.5, 0.0, 1.0, 1.0, -1, r);
      gmsh::model::occ::synchronize();
      const double area = 1.0 - (4.0 - std::numbers::pi) * r * r;
      mesh = mesh_to_target_count(area, target_elements, side_m);
    } catch (...) {
      throw std::runtime_error("mesh_rounded_square: Gmsh failed: " + describe_current_exception());
    }
  }
  sort_for_locality(mesh);  // finalizes too
  return mesh;
}

// The body is two half-cylinders glued at z = 0 (OCC's fragment makes their common disk one
// shared face), so the mid-plane is meshed as an interface: its rim, the circle r = R, z = 0,
// is a mesh curve carrying ~2 pi R / h nodes, where the solver reads the mid-plane rim.
Mesh mesh_cylinder(double radius_m, double thickness_m, int target_elements) {
  if (!(radius_m > 0.0) || !std::isfinite(radius_m)) {
    throw std::invalid_argument("mesh_cylinder: radius must be positive and finite");
  }
  if (!(thickness_m > 0.0) || !std::isfinite(thickness_m)) {
    throw std::invalid_argument("mesh_cylinder: thickness must be positive and finite");
  }
  check_target("mesh_cylinder", target_elements);
  const double t = thickness_m / radius_m;  // normalised to unit radius
  // OpenCASCADE's absolute tolerance is 1e-7 in these unit-radius coordinates; a much thinner
  // (or, relative to the height, much narrower) cylinder would fall below it.
  if (!(t >= kMinThicknessRatio) || !(t <= 1.0 / kMinThicknessRatio)) {
    throw std::invalid_argument(
        "mesh_cylinder: thickness must be within 1e-5 to 1e5 times the radius, got " +
        std::to_string(thickness_m) + " for radius " + std::to_string(radius_m));
  }
  Mesh mesh;
  {
    GmshSession session;
    try {
      gmsh::model::add("cylinder");
      const int lower = gmsh::model::occ::addCylinder(0.0, 0.0, -0.5 * t, 0.0, 0.0, 0.5 * t, 1.0);
      const int upper = gmsh::model::occ::addCylinder(0.0, 0.0, 0.0, 0.0, 0.0, 0.5 * t, 1.0);
      gmsh::vectorpair pieces;
      std::vector<gmsh::vectorpair> piece_map;
      gmsh::model::occ::fragment({{3, lower}}, {{3, upper}}, pieces, piece_map);
      gmsh::model::occ::synchronize();
      mesh = mesh_3d_to_target_count(std::numbers::pi * t, target_elements, radius_m);
    } catch (...) {
      throw std::runtime_error("mesh_cylinder: Gmsh failed: " + describe_current_exception());
    }
  }
  sort_for_locality(mesh);  // finalizes too
  return mesh;
}

Mesh mesh_sphere(double radius_m, int target_elements) {
  if (!(radius_m > 0.0) || !std::isfinite(radius_m)) {
    throw std::invalid_argument("mesh_sphere: radius must be positive and finite");
  }
  check_target("mesh_sphere", target_elements);
  Mesh mesh;
  {
    GmshSession session;
    try {
      gmsh::model::add("sphere");
      gmsh::model::occ::addSphere(0.0, 0.0, 0.0, 1.0);  // unit radius, scaled below
      gmsh::model::occ::synchronize();
      mesh = mesh_3d_to_target_count(4.0 / 3.0 * std::numbers::pi, target_elements, radius_m);
    } catch (...) {
      throw std::runtime_error("mesh_sphere: Gmsh failed: " + describe_current_exception());
    }
  }
  sort_for_locality(mesh);  // finalizes too
  return mesh;
}

Mesh read_gmsh_file(const std::string& path) {
  const std::string context = "read_gmsh_file: '" + path + "': ";
  try {
    std::error_code error;
    const auto status = std::filesystem::status(path, error);
    // Gmsh's open() silently does nothing for a missing file, so check first.
    if (!std::filesystem::exists(status)) {
      throw std::runtime_error(error ? error.message() : "no such file");
    }
    if (!std::filesystem::is_regular_file(status)) throw std::runtime_error("not a regular file");
    // Gmsh also runs "<file>.opt" next to the file as a script if one exists, so it reads a
    // private copy; the header check is on that copy, so the file cannot change in between.
    TemporaryDirectory directory;
    const std::filesystem::path copy = directory.path() / "mesh.msh";
    std::filesystem::copy_file(path, copy);
    if (!starts_like_msh(copy.string())) {
      throw std::runtime_error("not a Gmsh MSH file (no $MeshFormat header)");
    }
    // Gmsh allocates for the counts a header declares before it reads the items.
    (void)check_msh_counts(copy.string());
    Mesh mesh;
    {
      GmshSession session;
      try {
        // merge (unlike open) reports a missing file instead of starting a new model.
        gmsh::merge(copy.string());
        // Tetrahedra make it a 3-D mesh (whatever triangles bound them); otherwise the
        // triangles make a 2-D one. MSH coordinates are taken as metres.
        std::vector<int> types;
        gmsh::model::mesh::getElementTypes(types);
        const bool has_tetrahedra =
            std::find(types.begin(), types.end(), kGmshTetrahedron4) != types.end();
        mesh = extract_elements(has_tetrahedra ? kGmshTetrahedron4 : kGmshTriangle3, 1.0);
      } catch (...) {
        // Gmsh's messages name the copy; name the caller's file instead.
        std::string message = describe_current_exception();
        for (std::size_t at = message.find(copy.string()); at != std::string::npos;
             at = message.find(copy.string(), at + path.size())) {
          message.replace(at, copy.string().size(), path);
        }
        throw std::runtime_error("Gmsh: " + message);
      }
    }
    if (mesh.triangles.empty() && mesh.tetrahedra.empty()) {
      throw std::runtime_error("contains no 3-node triangles or 4-node tetrahedra");
    }
    finalize_mesh(mesh);  // 2-D or 3-D, as extracted
    return mesh;
  } catch (const std::exception& e) {
    throw std::runtime_error(context + e.what());
  }
}

}  // namespace softshock
