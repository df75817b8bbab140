// The module's entry points (see gmsh_plugin.hpp): gmsh_mesher.cpp's functions behind two
// C-named symbols. Everything else in the module is hidden, so its copies of mesh.cpp and
// gmsh_mesher.cpp never clash with the loader's symbols of the same names.
#include "solver/gmsh_plugin.hpp"

#include <exception>
#include <new>
#include <stdexcept>

#include "solver/gmsh_mesher.hpp"

namespace gp = softshock::gmsh_plugin;

extern "C" __attribute__((visibility("default"))) int softshock_gmsh_mesher_abi(
    std::size_t* mesh_size) {
  *mesh_size = sizeof(softshock::Mesh);
  return gp::kAbiVersion;
}

extern "C" __attribute__((visibility("default"))) int softshock_gmsh_mesher_mesh(
    const gp::Request* request, softshock::Mesh* out, std::string* error) {
  try {
    switch (request->shape) {
      case gp::Shape::kDisk:
        *out = softshock::mesh_disk(request->size_m, request->target_elements);
        return gp::kOk;
      case gp::Shape::kRoundedSquare:
        *out = softshock::mesh_rounded_square(request->size_m, request->corner_radius_m,
                                              request->target_elements);
        return gp::kOk;
      case gp::Shape::kCylinder:
        *out = softshock::mesh_cylinder(request->size_m, request->thickness_m,
                                        request->target_elements);
        return gp::kOk;
      case gp::Shape::kSphere:
        *out = softshock::mesh_sphere(request->size_m, request->target_elements);
        return gp::kOk;
      case gp::Shape::kFile:
        *out = softshock::read_gmsh_file(request->path ? request->path : "");
        return gp::kOk;
    }
    *error = "unknown mesher request";
    return gp::kInvalidArgument;
  } catch (const std::bad_alloc&) {  // also where building the message itself ran out
    return gp::kOutOfMemory;
  } catch (const std::invalid_argument& e) {
    *error = e.what();
    return gp::kInvalidArgument;
  } catch (const std::exception& e) {
    *error = e.what();
    return gp::kRuntimeError;
  } catch (...) {
    *error = "unknown error in the Gmsh mesher";
    return gp::kRuntimeError;
  }
}
