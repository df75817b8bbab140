// The room the catalogue keeps for itself on its disk: a file of allocated blocks
// (DATA/catalogue.room, 8 MiB) that nothing writes into. When the disk is full, SQLite cannot
// append to its write-ahead log, and every write fails -- also the ones that would free space.
// The writes that free space or record an outcome (DeleteJob, CancelJob, DeleteMesh's catalogue
// side, a run's end) are therefore run through with_room(): on SQLITE_FULL the room file is
// removed and the write tried once more, now with the freed blocks. Submissions never are, so
// they cannot eat the room. refill() takes the room back once there is space (after a deletion,
// and at start-up).
#pragma once

#include <cstdint>
#include <mutex>
#include <string>

#include "server/store/catalogue.hpp"

namespace softshock::server::detail {

class CatalogueRoom {
 public:
  CatalogueRoom(std::string path, std::int64_t bytes) : path_(std::move(path)), bytes_(bytes) {}
  // Makes the file hold `bytes` of allocated blocks (posix_fallocate, so the space is really
  // taken, also on file systems with sparse files). False when the disk lacks the room (a
  // partial file is removed); tried again on the next refill().
  bool refill();
  // Removes the file, freeing its blocks for the catalogue's next write. False if there was
  // none to remove.
  bool release();
  // Whether the file is there, whole.
  bool held() const;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::int64_t bytes_;
  mutable std::mutex mutex_;
};

// Runs `write` (a whole transaction); on CatalogueFull gives the room back and runs it once more.
template <typename F>
auto with_room(CatalogueRoom* room, F&& write) -> decltype(write()) {
  try {
    return write();
  } catch (const CatalogueFull&) {
    if (room == nullptr || !room->release()) throw;
  }
  return write();
}

}  // namespace softshock::server::detail
