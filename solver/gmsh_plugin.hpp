// The interface between softshock_solver and its Gmsh mesher, which is a separately loaded
// module (libsoftshock_gmsh_mesher.so, loaded with dlopen on first use). libgmsh pulls in
// ~90 shared libraries and costs ~0.15 s at process start; a run that reuses a cached mesh
// never needs it. Both sides are built from this tree by the same compiler, so C++ types may
// cross; the ABI number and sizeof(Mesh) catch a module from another build.
#pragma once

#include <string>

#include "solver/mesh.hpp"

namespace softshock::gmsh_plugin {

constexpr int kAbiVersion = 3;  // 3: cylinders and spheres, Request::thickness_m
constexpr const char* kModuleName = "libsoftshock_gmsh_mesher.so";
constexpr const char* kAbiSymbol = "softshock_gmsh_mesher_abi";    // AbiFn
constexpr const char* kMeshSymbol = "softshock_gmsh_mesher_mesh";  // MeshFn

enum class Shape : int { kDisk = 1, kRoundedSquare = 2, kFile = 3, kCylinder = 4, kSphere = 5 };

struct Request {
  Shape shape = Shape::kDisk;
  double size_m = 0;           // disk, cylinder or sphere radius, or square side
  double corner_radius_m = 0;  // rounded square only
  double thickness_m = 0;      // cylinder only
  int target_elements = 0;
  const char* path = nullptr;  // kFile only
};

// What a call returned: the C++ exception the in-process mesher threw, as a code.
enum Status : int { kOk = 0, kInvalidArgument = 1, kRuntimeError = 2, kOutOfMemory = 3 };

using AbiFn = int (*)(std::size_t* mesh_size);
// Fills *out (finalized mesh) or *error; never throws.
using MeshFn = int (*)(const Request* request, Mesh* out, std::string* error);

}  // namespace softshock::gmsh_plugin
