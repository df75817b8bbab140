#include "server/store/file_digests.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "server/store/spec_hash.hpp"

namespace softshock::server {

std::optional<std::string> FileDigests::digest(int fd, const std::function<bool()>& cancelled) {
  struct stat st {};
  if (::fstat(fd, &st) != 0)
    throw std::runtime_error(std::string("fstat: ") + std::strerror(errno));
  const Key key{st.st_dev, st.st_ino, static_cast<int64_t>(st.st_size),
                static_cast<int64_t>(st.st_mtim.tv_sec) * 1'000'000'000 + st.st_mtim.tv_nsec};
  {
    std::lock_guard lock(mutex_);
    if (auto it = memo_.find(key); it != memo_.end()) return it->second;
  }
  // Hashed outside the lock: two downloads of different files do not wait for each other (two of
  // the same file may both hash it once).
  Sha256 hash;
  std::vector<char> block(std::size_t{1} << 20);
  for (int64_t at = 0; at < st.st_size;) {
    if (cancelled && cancelled()) return std::nullopt;
    const ssize_t n = ::pread(fd, block.data(), block.size(), at);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw std::runtime_error(std::string("read: ") + std::strerror(errno));
    if (n == 0) throw std::runtime_error("the file ended before its size");
    hash.update(std::string_view(block.data(), static_cast<std::size_t>(n)));
    at += n;
  }
  std::string hex = hash.hex_digest();
  std::lock_guard lock(mutex_);
  ++computed_;
  if (memo_.emplace(key, hex).second) {
    order_.push_back(key);
    while (order_.size() > max_entries_) {
      memo_.erase(order_.front());
      order_.pop_front();
    }
  }
  return hex;
}

std::size_t FileDigests::computed() const {
  std::lock_guard lock(mutex_);
  return computed_;
}

}  // namespace softshock::server
