#include "server/store/catalogue_room.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>

#include "server/log.hpp"

namespace softshock::server::detail {

bool CatalogueRoom::refill() {
  std::lock_guard lock(mutex_);
  const int fd = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0600);
  if (fd < 0) return false;
  int rc = ::posix_fallocate(fd, 0, static_cast<off_t>(bytes_));
  if (rc == EOPNOTSUPP || rc == EINVAL) {
    // A file system without fallocate: write the zeros instead.
    static const char zeros[1 << 16] = {};
    rc = 0;
    for (std::int64_t done = 0; done < bytes_ && rc == 0;) {
      const auto n = ::pwrite(
          fd, zeros, static_cast<std::size_t>(std::min<std::int64_t>(sizeof zeros, bytes_ - done)),
          static_cast<off_t>(done));
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        rc = errno == 0 ? ENOSPC : errno;
      } else {
        done += n;
      }
    }
  }
  if (rc == 0 && ::fsync(fd) != 0) rc = errno;
  ::close(fd);
  if (rc != 0) {
    ::unlink(path_.c_str());  // half a room is no room; and it gives its blocks back
    return false;
  }
  return true;
}

bool CatalogueRoom::release() {
  std::lock_guard lock(mutex_);
  if (::unlink(path_.c_str()) != 0) return false;
  log_warning("the disk is full: the catalogue used its reserved room (", path_,
              ") to record a deletion or an outcome; it takes it back once there is space");
  return true;
}

bool CatalogueRoom::held() const {
  std::lock_guard lock(mutex_);
  struct stat st {};
  return ::stat(path_.c_str(), &st) == 0 && static_cast<std::int64_t>(st.st_blocks) * 512 >= bytes_;
}

}  // namespace softshock::server::detail
