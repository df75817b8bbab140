#include "solver/io/hdf5_support.hpp"

#include <cstdio>
#include <stdexcept>

namespace softshock::h5 {

std::string frame_group_name(std::size_t k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame_%05zu", k);
  return buf;
}

std::unique_lock<std::mutex> lock_hdf5() {
  static std::mutex mutex;
  std::unique_lock<std::mutex> lock(mutex);
  // Errors become exceptions with the library's own message (see fail()); the default handler
  // would also print the whole stack to stderr, into the daemon's log. Set on every lock because
  // a thread-safe libhdf5 keeps this setting per thread.
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  return lock;
}

namespace {

// The innermost (most specific) description on HDF5's error stack, e.g. "unable to open file:
// name = '...', errno = 2, error message = 'No such file or directory'". Clears the stack.
std::string hdf5_error_detail() {
  std::string detail;
  H5Ewalk2(
      H5E_DEFAULT, H5E_WALK_UPWARD,
      [](unsigned n, const H5E_error2_t* err, void* data) -> herr_t {
        if (n == 0 && err->desc) *static_cast<std::string*>(data) = err->desc;
        return 0;
      },
      &detail);
  H5Eclear2(H5E_DEFAULT);
  return detail;
}

}  // namespace

[[noreturn]] void fail(const std::string& what, const std::string& path) {
  const std::string detail = hdf5_error_detail();
  throw std::runtime_error("HDF5: " + what + " (" + path + ")" +
                           (detail.empty() ? "" : ": " + detail));
}

Hid checked(hid_t id, const std::string& what, const std::string& path) {
  if (id < 0) fail(what, path);
  return Hid(id);
}
void checked(herr_t rc, const std::string& what, const std::string& path) {
  if (rc < 0) fail(what, path);
}

Hid file_access_plist(const std::string& path) {
  Hid fapl = checked(H5Pcreate(H5P_FILE_ACCESS), "create file access list", path);
  checked(H5Pset_fclose_degree(fapl.get(), H5F_CLOSE_STRONG), "set close degree", path);
  checked(H5Pset_file_locking(fapl.get(), 1, 1), "set file locking", path);
  return fapl;
}

}  // namespace softshock::h5
