// HDF5 plumbing shared by the result file's writer (result_writer.cpp) and reader
// (result_reader.cpp): the layout's names and version, the process-wide HDF5 lock, owned
// identifiers and errors as exceptions. Private to softshock_results.
#pragma once

#include <hdf5.h>

#include <array>
#include <cstddef>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "solver/simulation.hpp"

namespace softshock::h5 {

// 2: node vectors are N x 3 (z = 0 in 2-D), so ParaView's default XDMF reader offers Warp By
// Vector. Version 1 files (N x 2) are still read. 3-D results (tetrahedra) are version 2 too:
// they add datasets (/mesh/tetrahedra, /mesh/boundary_faces) and the root attribute `dimension`
// rather than change a 2-D one, and a 2-D file stays as it was.
inline constexpr int kFormatVersion = 2;
inline constexpr std::size_t kVectorColumns = 3;
inline constexpr const char* kH5Name = "result.h5";
inline constexpr const char* kXdmfName = "result.xdmf";

// The per-frame fields: dataset name, node-centred (N x dimension in memory, N x 3 on disk) or
// per element (E), member, units.
struct FieldSpec {
  const char* name;
  bool nodal;
  std::vector<double> FieldFrame::*member;
  const char* units;
};
inline constexpr std::array<FieldSpec, 8> kFields{{
    {"displacement", true, &FieldFrame::displacement, "m"},
    {"velocity", true, &FieldFrame::velocity, "m/s"},
    {"J", false, &FieldFrame::J, "1"},
    {"mean_stress", false, &FieldFrame::mean_stress, "Pa"},
    {"radial_stress", false, &FieldFrame::radial_stress, "Pa"},
    {"hoop_stress", false, &FieldFrame::hoop_stress, "Pa"},
    {"von_mises", false, &FieldFrame::von_mises, "Pa"},
    {"aspect_ratio", false, &FieldFrame::aspect_ratio, "1"},
}};

// The phase-field damage d, one value per node (N, also in 3-D), in every frame of a run with
// damage and in none without (FieldFrame::damage empty).
inline constexpr FieldSpec kDamageField{"damage", true, &FieldFrame::damage, "1"};

// "frame_00042": the group of frame k under /fields.
std::string frame_group_name(std::size_t k);

// libhdf5 keeps global state (identifier tables, caches, free lists) shared by all files and
// is safe for threads only when built with --enable-threadsafe. Debian 12's build is, but other
// builds (a self-built or vendored HDF5) are not, so every HDF5 call of this module goes through
// one process-wide mutex whatever the build. Handles are closed under it too: declare the lock
// before any Hid in a scope so it is released last.
std::unique_lock<std::mutex> lock_hdf5();

// Throws std::runtime_error naming the operation, the file and HDF5's innermost message.
[[noreturn]] void fail(const std::string& what, const std::string& path);

// Owner of one HDF5 identifier. Must be destroyed with the HDF5 lock held.
class Hid {
 public:
  Hid() = default;
  explicit Hid(hid_t id) : id_(id) {}
  Hid(Hid&& o) noexcept : id_(std::exchange(o.id_, H5I_INVALID_HID)) {}
  Hid& operator=(Hid&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = std::exchange(o.id_, H5I_INVALID_HID);
    }
    return *this;
  }
  Hid(const Hid&) = delete;
  Hid& operator=(const Hid&) = delete;
  ~Hid() { reset(); }

  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }
  // Gives up ownership (for closes whose status matters, e.g. H5Fclose).
  hid_t release() { return std::exchange(id_, H5I_INVALID_HID); }
  // H5Idec_ref closes any kind of identifier (file, group, dataset, type, space, plist).
  void reset() {
    if (id_ >= 0) H5Idec_ref(id_);
    id_ = H5I_INVALID_HID;
  }

 private:
  hid_t id_ = H5I_INVALID_HID;
};

// The identifier, owned; fail() when it is negative (an HDF5 error).
Hid checked(hid_t id, const std::string& what, const std::string& path);
void checked(herr_t rc, const std::string& what, const std::string& path);

// File access properties: close everything still open with the file (so H5Fclose really
// releases it before the fsync and rename), and use file locks where the filesystem has them
// without failing where it has none (NFS without lockd).
Hid file_access_plist(const std::string& path);

}  // namespace softshock::h5
