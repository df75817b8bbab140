#include "solver/io/checkpoint_folder.hpp"

#include <cstdio>
#include <filesystem>
#include <system_error>
#include <utility>

#include "softshock/version.hpp"
#include "solver/run_summary.hpp"

namespace softshock {

namespace fs = std::filesystem;

std::optional<Checkpoint> load_checkpoint_folder(const std::string& folder,
                                                 const std::string& spec_json, const Mesh& mesh,
                                                 int threads, std::string* why_not) {
  const fs::path path = fs::path(folder) / kCheckpointStateFile;
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  auto refuse = [&](const std::string& why) -> std::optional<Checkpoint> {
    if (why_not) *why_not = why;
    return std::nullopt;
  };
  Checkpoint c;
  try {
    c = read_checkpoint(path.string());
  } catch (const std::exception& e) {
    return refuse(e.what());
  }
  if (c.header.spec_json != spec_json) return refuse("taken for another spec");
  if (c.header.mesh_fingerprint != mesh_fingerprint(mesh)) return refuse("taken on another mesh");
  if (c.state.threads != threads) {
    return refuse("taken with " + std::to_string(c.state.threads) +
                  " solver thread(s), this run has " + std::to_string(threads) +
                  " (the sums' order would differ)");
  }
  for (const auto& sealed : checkpoint_segments(folder, c.header)) {
    if (!fs::exists(sealed.path, ec)) return refuse("its frame file " + sealed.path + " is gone");
  }
  return c;
}

std::vector<ResultWriter::Sealed> checkpoint_segments(const std::string& folder,
                                                      const CheckpointHeader& header) {
  std::vector<ResultWriter::Sealed> out;
  for (const auto& s : header.segments)
    out.push_back({(fs::path(folder) / s.file).string(), s.frames});
  return out;
}

std::string write_checkpoint_folder(AsyncResultWriter& writer, const std::string& folder,
                                    const std::string& spec_json,
                                    const std::string& mesh_fingerprint, const RunState& state,
                                    std::function<void(const std::string& error)> done) {
  Checkpoint c;
  c.header.solver_revision = kSolverRevision;
  c.header.solver_version = SOFTSHOCK_VERSION;
  c.header.spec_json = spec_json;
  c.header.mesh_fingerprint = mesh_fingerprint;
  c.state = state;
  // Named by step: a continued run's files never take the name of one its checkpoint lists.
  char name[48];
  std::snprintf(name, sizeof name, "frames_%012lld.h5", static_cast<long long>(state.steps));
  const std::string state_path = (fs::path(folder) / kCheckpointStateFile).string();
  writer.checkpoint(std::move(c), (fs::path(folder) / name).string(), state_path, std::move(done));
  return state_path;
}

double checkpoint_state_bytes(const RunState& s) {
  double bytes = 0;
  for (const auto& a : s.arrays) bytes += 8.0 * a.f64.size() + 4.0 * a.f32.size();
  for (const auto& column : s.history.columns()) bytes += 8.0 * column.second->size();
  for (const auto& row : s.history.modes) bytes += 8.0 * row.size();
  for (const auto& row : s.history.modes_z_mean) bytes += 8.0 * row.size();
  return bytes;
}

}  // namespace softshock
