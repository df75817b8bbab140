// Where a spec's geometry.mesh_file is read from when a host confines mesh files to one folder
// (softshockd: DATA/meshes/). The client's name is resolved under that folder only, symlinks
// included, before anything else touches it; every way of failing gives the same message, so
// the answer never tells which files exist elsewhere on the host.
#pragma once

#include <string>

namespace softshock {

// The canonical absolute path of the regular file `name` (a relative path without "..") inside
// `root`, after following every symlink. Throws SpecError("geometry.mesh_file", one fixed text)
// if the name is malformed, absent, not a regular file, or leads out of `root`.
std::string resolve_mesh_file(const std::string& root, const std::string& name);

}  // namespace softshock
