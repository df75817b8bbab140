#include "solver/mesh_file_path.hpp"

#include <filesystem>

#include "solver/run_spec.hpp"

namespace softshock {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t kMaxNameLength = 1024;

[[noreturn]] void unusable() {
  // One text for absent, outside, malformed and not-a-file alike (no existence oracle).
  throw SpecError("geometry.mesh_file",
                  "names no mesh file in the daemon's meshes folder (a relative path, without "
                  "'..', to a regular .msh file inside DATA/meshes/)");
}

}  // namespace

std::string resolve_mesh_file(const std::string& root, const std::string& name) {
  if (name.empty() || name.size() > kMaxNameLength) unusable();
  for (unsigned char c : name) {
    if (c < 0x20 || c == 0x7f) unusable();  // NUL would cut the path short for the OS
  }
  const fs::path relative(name);
  if (relative.is_absolute() || relative.has_root_name() || relative.has_root_directory()) {
    unusable();
  }
  for (const auto& part : relative) {
    if (part == "..") unusable();
  }
  std::error_code ec;
  const fs::path base = fs::canonical(root, ec);
  if (ec) unusable();
  const fs::path target = fs::canonical(base / relative, ec);
  if (ec) unusable();
  // Symlinks are resolved by canonical(): what they lead to must still lie inside the folder.
  const std::string prefix = base.string() + "/";
  if (target.string().compare(0, prefix.size(), prefix) != 0) unusable();
  if (!fs::is_regular_file(target, ec) || ec) unusable();
  return target.string();
}

}  // namespace softshock
