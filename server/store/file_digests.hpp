// SHA-256 of result files, remembered by the file's identity (device, inode, size, modification
// time): a download that comes back for the next part of a multi-gigabyte result.h5 is not hashed
// again. A finished job's files never change; a file that did (another inode, size or time) is
// hashed anew. Thread-safe.
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <tuple>

namespace softshock::server {

class FileDigests {
 public:
  explicit FileDigests(std::size_t max_entries = 1024) : max_entries_(max_entries) {}

  // Lower-case hex SHA-256 of the whole open file `fd` (read with pread from 0 to the size fstat
  // gives). `cancelled` is asked between blocks of 1 MiB: true ends the reading with nullopt.
  // Throws std::runtime_error on a read error.
  std::optional<std::string> digest(int fd, const std::function<bool()>& cancelled);

  // Files hashed so far (for tests: the second call on the same file is served from memory).
  std::size_t computed() const;

 private:
  using Key = std::tuple<dev_t, ino_t, int64_t, int64_t>;  // device, inode, size, mtime ns
  mutable std::mutex mutex_;
  std::map<Key, std::string> memo_;
  std::deque<Key> order_;  // oldest first, for eviction
  std::size_t max_entries_;
  std::size_t computed_ = 0;
};

}  // namespace softshock::server
