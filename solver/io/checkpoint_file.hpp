// Checkpoint files: a run's restart state (solver/run_state.hpp) with what is needed to check it
// belongs to a run and to continue that run's result file (docs/reliability.md, "Checkpoints").
// A simple versioned binary of named records, each array whole, with a 64-bit
// checksum over everything before the end record: a truncated or altered file is refused, never
// half-read. Written to a temporary name, fsynced and renamed, so a crash leaves either the old
// checkpoint or the new one. Plain file I/O: no HDF5, so the process-wide HDF5 lock that result
// files share is never held for a checkpoint.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "solver/mesh.hpp"
#include "solver/run_state.hpp"

namespace softshock {

// 1: the first format. A reader refuses any other number.
inline constexpr int kCheckpointFormat = 1;

// A checkpoint that cannot be used: unreadable, truncated, altered, of another format or solver
// revision, or of another run. The message says which, in words for a job's log.
class CheckpointError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The result's frames so far: sealed HDF5 files (ResultWriter::seal_segment), in order, named
// relative to the checkpoint file's folder, each holding `frames` frames under /fields with the
// run's frame numbering.
struct CheckpointSegment {
  std::string file;
  std::size_t frames = 0;
};

struct CheckpointHeader {
  int solver_revision = 0;       // run_summary.hpp's kSolverRevision when written
  std::string solver_version;    // SOFTSHOCK_VERSION of the writer (informative)
  std::string spec_json;         // the run's normalised spec
  std::string mesh_fingerprint;  // mesh_fingerprint() of the run's mesh
  std::vector<CheckpointSegment> segments;
  std::vector<double> frame_times;  // s, one per frame of the segments
};

struct Checkpoint {
  CheckpointHeader header;
  RunState state;
};

// Writes `path` durably: path + ".tmp", fsync, rename over `path`, fsync of the folder. Throws
// std::runtime_error naming the path and the errno (ENOSPC among them); the temporary file is
// removed on failure.
void write_checkpoint(const std::string& path, const Checkpoint& checkpoint);

// Reads and verifies a checkpoint (format, checksum, this solver's revision). Throws
// CheckpointError.
Checkpoint read_checkpoint(const std::string& path);

// A digest of the mesh (coordinates and connectivity, bit for bit), 16 hex digits: a checkpoint
// is continued only on the mesh it was taken on.
std::string mesh_fingerprint(const Mesh& mesh);

// The format's 64-bit checksum of a byte stream fed in pieces (the same value however it is cut):
// FNV-1a over 8-byte little-endian words, the length and a final avalanche. Every change of a
// single word changes it. Exposed for tests that alter a file and mend its checksum.
class CheckpointChecksum {
 public:
  void update(const void* data, std::size_t bytes);
  std::uint64_t value() const;

 private:
  std::uint64_t hash_ = 0xcbf29ce484222325ull;
  std::uint64_t length_ = 0;
  unsigned char pending_[8] = {};
  std::size_t pending_bytes_ = 0;
};

}  // namespace softshock
