// A folder of restartable checkpoints of one run: state.ckpt (checkpoint_file.hpp) and the frames
// computed so far, sealed into frames_<step>.h5 (AsyncResultWriter::checkpoint). The same folder
// serves softshockd's jobs (server/jobs/job_checkpoint.hpp, which schedules and logs them) and
// softshock-solve --checkpoint-dir (a run on a cluster node, continued when Slurm runs it again).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "solver/io/async_result_writer.hpp"
#include "solver/io/checkpoint_file.hpp"
#include "solver/mesh.hpp"
#include "solver/run_state.hpp"

namespace softshock {

inline constexpr const char* kCheckpointStateFile = "state.ckpt";

// The folder's checkpoint when it can continue this run: the same normalised spec, mesh
// (fingerprint) and solver thread count, and every sealed frame file present. nullopt when there
// is none, or (with `why_not` set) when it cannot be used.
std::optional<Checkpoint> load_checkpoint_folder(const std::string& folder,
                                                 const std::string& spec_json, const Mesh& mesh,
                                                 int threads, std::string* why_not);

// The checkpoint's sealed frame files, as paths for the continued result writer.
std::vector<ResultWriter::Sealed> checkpoint_segments(const std::string& folder,
                                                      const CheckpointHeader& header);

// Hands a checkpoint of `state` to the writer's thread: the frames so far sealed into
// frames_<step>.h5, then state.ckpt written by temporary file + rename. `done(error)` runs there
// (error empty: written; else the previous checkpoint stays in force). Returns state.ckpt's path.
std::string write_checkpoint_folder(AsyncResultWriter& writer, const std::string& folder,
                                    const std::string& spec_json,
                                    const std::string& mesh_fingerprint, const RunState& state,
                                    std::function<void(const std::string& error)> done);

// Bytes the state takes in a checkpoint file, near enough for a free-space check.
double checkpoint_state_bytes(const RunState& state);

}  // namespace softshock
