// Continuing a finished job to a later end time (ExtendJob, docs/api.md). A SUCCEEDED job run in
// process keeps the state where its run stopped, DATA/jobs/<id>/final_state.ckpt (its frames are
// in its result.h5). A job extending it starts from that state, with the parent's result.h5
// hard-linked into its own checkpoint folder as the first sealed segment of its frames, so it
// neither recomputes the parent's steps nor copies its file twice; when the parent's end time lies
// on the output and history schedule its result is bitwise the one a run straight to the later
// end time writes (tests/integration/test_extend.py). Without a usable state (another solver
// revision or thread count, a parent run before states were kept) the job runs from t = 0.
#pragma once

#include <optional>
#include <string>

#include "solver/io/checkpoint_file.hpp"
#include "solver/mesh.hpp"
#include "solver/run_state.hpp"

namespace softshock::server {

// DATA/jobs/<id>/final_state.ckpt
std::string final_state_path(const std::string& job_dir);

// Keeps a finished run's stopped state (temporary file + rename), its frame times read from the
// finished result.h5. Throws std::runtime_error.
void save_final_state(const std::string& job_dir, const std::string& spec_json,
                      const std::string& mesh_fingerprint, const RunState& stopped,
                      const std::string& result_h5);

// The parent's final state when this run can continue it: the same normalised spec but for
// run.end_time (which must be later), the same mesh and solver thread count. Its frames are
// linked (or copied) to <job_dir>/checkpoint/parent_frames.h5 and named as the checkpoint's one
// segment, so sealed_frames(job_dir, header) finds them. nullopt with `why_not` set otherwise.
std::optional<Checkpoint> load_parent_state(const std::string& parent_dir,
                                            const std::string& job_dir,
                                            const std::string& spec_json, const Mesh& mesh,
                                            int threads, std::string* why_not);

}  // namespace softshock::server
