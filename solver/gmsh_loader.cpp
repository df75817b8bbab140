// gmsh_mesher.hpp as the solver library provides it: each call loads the Gmsh mesher module
// (gmsh_plugin.hpp) on first use and forwards to it. A process that never meshes (a run with a
// cached mesh) never maps libgmsh and its ~90 dependencies.
//
// The module is looked for in order: $SOFTSHOCK_GMSH_MESHER (a path), next to the executable,
// in ../lib/softshock/ beside the executable's folder (installed layout), and where this build
// tree put it.
#include <dlfcn.h>

#include <filesystem>
#include <fstream>
#include <mutex>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include "solver/gmsh_mesher.hpp"
#include "solver/gmsh_plugin.hpp"

#ifndef SOFTSHOCK_GMSH_MESHER_BUILD_PATH
#define SOFTSHOCK_GMSH_MESHER_BUILD_PATH ""
#endif
#ifndef SOFTSHOCK_GMSH_VERSION
#define SOFTSHOCK_GMSH_VERSION "unknown"
#endif

namespace softshock {
namespace {

namespace fs = std::filesystem;
namespace gp = gmsh_plugin;

std::vector<std::string> candidate_paths() {
  if (const char* env = std::getenv("SOFTSHOCK_GMSH_MESHER"); env != nullptr && *env != '\0') {
    return {env};
  }
  std::vector<std::string> paths;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    paths.push_back((exe.parent_path() / gp::kModuleName).string());
    paths.push_back((exe.parent_path().parent_path() / "lib" / "softshock" / gp::kModuleName)
                        .lexically_normal()
                        .string());
  }
  if (*SOFTSHOCK_GMSH_MESHER_BUILD_PATH != '\0')
    paths.emplace_back(SOFTSHOCK_GMSH_MESHER_BUILD_PATH);
  return paths;
}

struct Module {
  gp::MeshFn mesh = nullptr;
  std::string error;  // why it could not be loaded (then mesh is null)
};

Module load_module() {
  Module m;
  std::string tried;
  for (const std::string& path : candidate_paths()) {
    std::error_code ec;
    if (!fs::exists(path, ec)) {
      tried += "\n  " + path + ": no such file";
      continue;
    }
    // Never unloaded: Gmsh keeps global state and registers exit handlers.
    void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) {
      const char* why = dlerror();
      tried += "\n  " + path + ": " + (why ? why : "dlopen failed");
      continue;
    }
    auto abi = reinterpret_cast<gp::AbiFn>(dlsym(handle, gp::kAbiSymbol));
    auto mesh = reinterpret_cast<gp::MeshFn>(dlsym(handle, gp::kMeshSymbol));
    std::size_t mesh_size = 0;
    if (abi == nullptr || mesh == nullptr || abi(&mesh_size) != gp::kAbiVersion ||
        mesh_size != sizeof(Mesh)) {
      tried += "\n  " + path + ": from another build of softshock (interface mismatch)";
      continue;
    }
    m.mesh = mesh;
    return m;
  }
  m.error = "cannot load the Gmsh mesher module " + std::string(gp::kModuleName) +
            " (set SOFTSHOCK_GMSH_MESHER to its path); tried:" + tried;
  return m;
}

std::once_flag g_once;
Module g_module;

Mesh call(const gp::Request& request) {
  std::call_once(g_once, [] { g_module = load_module(); });
  if (g_module.mesh == nullptr) throw std::runtime_error(g_module.error);
  Mesh mesh;
  std::string error;
  switch (g_module.mesh(&request, &mesh, &error)) {
    case gp::kOk:
      return mesh;
    case gp::kInvalidArgument:
      throw std::invalid_argument(error);
    case gp::kOutOfMemory:
      throw std::bad_alloc();
    default:
      throw std::runtime_error(error);
  }
}

}  // namespace

Mesh mesh_disk(double radius_m, int target_elements) {
  gp::Request r;
  r.shape = gp::Shape::kDisk;
  r.size_m = radius_m;
  r.target_elements = target_elements;
  return call(r);
}

Mesh mesh_rounded_square(double side_m, double corner_radius_m, int target_elements) {
  gp::Request r;
  r.shape = gp::Shape::kRoundedSquare;
  r.size_m = side_m;
  r.corner_radius_m = corner_radius_m;
  r.target_elements = target_elements;
  return call(r);
}

Mesh mesh_cylinder(double radius_m, double thickness_m, int target_elements) {
  gp::Request r;
  r.shape = gp::Shape::kCylinder;
  r.size_m = radius_m;
  r.thickness_m = thickness_m;
  r.target_elements = target_elements;
  return call(r);
}

Mesh mesh_sphere(double radius_m, int target_elements) {
  gp::Request r;
  r.shape = gp::Shape::kSphere;
  r.size_m = radius_m;
  r.target_elements = target_elements;
  return call(r);
}

Mesh read_gmsh_file(const std::string& path) {
  gp::Request r;
  r.shape = gp::Shape::kFile;
  r.path = path.c_str();
  return call(r);
}

bool gmsh_mesher_loaded() {
  // Asks the kernel rather than our own flag: what matters is whether libgmsh is mapped.
  std::ifstream maps("/proc/self/maps");
  std::string line;
  while (std::getline(maps, line)) {
    if (line.find("/libgmsh.so") != std::string::npos) return true;
  }
  return false;
}

std::string gmsh_version() {
  return SOFTSHOCK_GMSH_VERSION;
}

}  // namespace softshock
