// Checkpoints (solver/run_state.hpp, solver/io/checkpoint_file.hpp): a run continued from a
// state taken at any step -- written to a checkpoint file and read back -- gives bitwise the
// history, frames and step counts of the run that never stopped, in 2-D and 3-D, on one thread
// and two; a run continued from where a run stopped at its end time equals a longer run; the file
// refuses damage, truncation and another solver revision; the result file continued from sealed
// frames equals one written in one go.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <string>
#include <vector>

#include "scratch_dir.hpp"
#include "solver/io/async_result_writer.hpp"
#include "solver/io/checkpoint_file.hpp"
#include "solver/io/result_file.hpp"
#include "solver/run_spec.hpp"
#include "solver/run_state.hpp"
#include "solver/run_summary.hpp"
#include "solver/simulation.hpp"

namespace softshock {
namespace {

using testing::ScratchDir;

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

// Every series and mode table of two histories, bit for bit; names the first that differs.
std::string history_difference(const History& a, const History& b) {
  const auto ca = a.columns(), cb = b.columns();
  if (ca.size() != cb.size())
    return "the columns (" + std::to_string(ca.size()) + " vs " + std::to_string(cb.size()) + ")";
  for (std::size_t k = 0; k < ca.size(); ++k)
    if (!same_bits(*ca[k].second, *cb[k].second)) return ca[k].first;
  if (a.modes.size() != b.modes.size()) return "modes";
  for (std::size_t k = 0; k < a.modes.size(); ++k)
    if (!same_bits(a.modes[k], b.modes[k])) return "modes";
  if (a.modes_z_mean.size() != b.modes_z_mean.size()) return "modes_z_mean";
  for (std::size_t k = 0; k < a.modes_z_mean.size(); ++k)
    if (!same_bits(a.modes_z_mean[k], b.modes_z_mean[k])) return "modes_z_mean";
  return "";
}

std::string frame_difference(const FieldFrame& a, const FieldFrame& b) {
  if (std::memcmp(&a.time_s, &b.time_s, sizeof a.time_s) != 0) return "time";
  const std::pair<const char*, std::vector<double> FieldFrame::*> fields[] = {
      {"displacement", &FieldFrame::displacement},
      {"velocity", &FieldFrame::velocity},
      {"J", &FieldFrame::J},
      {"mean_stress", &FieldFrame::mean_stress},
      {"radial_stress", &FieldFrame::radial_stress},
      {"hoop_stress", &FieldFrame::hoop_stress},
      {"von_mises", &FieldFrame::von_mises},
      {"aspect_ratio", &FieldFrame::aspect_ratio},
      {"damage", &FieldFrame::damage}};
  for (const auto& [name, member] : fields)
    if (!same_bits(a.*member, b.*member)) return name;
  return "";
}

struct Outcome {
  RunResult result;
  std::vector<FieldFrame> frames;
  std::vector<RunState> states;  // checkpoints taken
};

// Runs with frames kept; `take(progress)` says after which steps to take a checkpoint.
Outcome run(const Problem& problem, const SolverOptions& options,
            const std::function<bool(const Progress&)>& take = {}, const RunState* resume = nullptr,
            bool at_stop = false) {
  Outcome r;
  RunControl control;
  control.on_frame = [&](FieldFrame f) { r.frames.push_back(std::move(f)); };
  control.checkpoint_due = take;
  control.on_checkpoint = [&](const RunState& s) { r.states.push_back(s); };
  control.checkpoint_at_stop = at_stop;
  control.resume = resume;
  r.result = run_simulation(problem, options, control);
  return r;
}

struct Case {
  const char* name;
  const char* spec;
  int threads;
};
void PrintTo(const Case& c, std::ostream* os) {
  *os << c.name;
}  // not gtest's byte dump

class CheckpointBitwise : public ::testing::TestWithParam<Case> {};

// A state taken after any step, through a checkpoint file, continues to bitwise the same answer.
TEST_P(CheckpointBitwise, ContinuedRunsEqualTheRunThatNeverStopped) {
  const v1::RunSpec spec = normalize_spec(parse_spec_json(GetParam().spec));
  const Problem problem = make_problem(spec);
  SolverOptions options = make_options(spec);
  options.threads = GetParam().threads;
  const Outcome reference = run(problem, options);
  ASSERT_EQ(reference.result.status, RunStatus::kCompleted) << reference.result.error;
  const int64_t steps = reference.result.steps;
  ASSERT_GT(steps, 20);
  if (reference.result.history.damage) {  // the damage case must damage, or it shows nothing
    ASSERT_GT(reference.result.history.damage_dissipation.back(), 0.0);
  }

  // Checkpoints every step: taking them must not change the run.
  const Outcome taken = run(problem, options, [](const Progress&) { return true; });
  ASSERT_EQ(taken.states.size(), static_cast<std::size_t>(steps));
  EXPECT_EQ(history_difference(reference.result.history, taken.result.history), "");
  ASSERT_EQ(taken.frames.size(), reference.frames.size());

  // Continue from the first step, a state right after a frame, one right after a history sample
  // between frames, the middle and the step before the end.
  std::vector<std::size_t> picks = {0, static_cast<std::size_t>(steps / 2),
                                    static_cast<std::size_t>(steps - 2)};
  bool after_frame = false, after_sample = false;
  for (std::size_t k = 1; k < taken.states.size() && !(after_frame && after_sample); ++k) {
    const RunState& s = taken.states[k];
    const bool frame = s.last_frame_time_s == s.time_s;
    const bool sample = s.history.time.back() == s.time_s;
    if (frame && !after_frame) picks.push_back(k), after_frame = true;
    if (sample && !frame && !after_sample) picks.push_back(k), after_sample = true;
  }
  ASSERT_TRUE(after_frame && after_sample);

  ScratchDir dir("checkpoint");
  for (const std::size_t k : picks) {
    SCOPED_TRACE("continued after step " + std::to_string(k + 1));
    Checkpoint written;
    written.state = taken.states[k];
    written.header.solver_revision = kSolverRevision;
    written.header.frame_times.assign(written.state.frames_written, 0.0);
    const std::string path = dir.str("state.ckpt");
    write_checkpoint(path, written);
    const Checkpoint read = read_checkpoint(path);

    const Outcome continued = run(problem, options, {}, &read.state);
    ASSERT_EQ(continued.result.status, RunStatus::kCompleted) << continued.result.error;
    EXPECT_EQ(continued.result.steps, steps);
    EXPECT_EQ(history_difference(reference.result.history, continued.result.history), "");
    EXPECT_EQ(continued.result.min_dt_s, reference.result.min_dt_s);
    EXPECT_EQ(continued.result.max_dt_s, reference.result.max_dt_s);
    const std::size_t before = read.state.frames_written;
    ASSERT_EQ(before + continued.frames.size(), reference.frames.size());
    EXPECT_EQ(continued.result.frames_written, reference.result.frames_written);
    for (std::size_t f = 0; f < continued.frames.size(); ++f)
      EXPECT_EQ(frame_difference(reference.frames[before + f], continued.frames[f]), "")
          << "frame " << before + f;
  }
}

// The stopped state at the end time continues to a later end time: bitwise a run to that time
// when the first end time is on the history and output schedule.
TEST_P(CheckpointBitwise, ARunContinuedPastItsEndTimeEqualsALongerRun) {
  const v1::RunSpec spec = normalize_spec(parse_spec_json(GetParam().spec));
  const Problem problem = make_problem(spec);
  SolverOptions longer = make_options(spec);
  longer.threads = GetParam().threads;
  SolverOptions shorter = longer;
  shorter.end_time_s = longer.end_time_s / 2;  // a multiple of both intervals here
  const Outcome first = run(problem, shorter, {}, nullptr, true);
  ASSERT_EQ(first.states.size(), 1u);
  EXPECT_TRUE(first.states[0].stopped);
  const Outcome reference = run(problem, longer);
  const Outcome continued = run(problem, longer, {}, &first.states[0]);
  ASSERT_EQ(continued.result.status, RunStatus::kCompleted) << continued.result.error;
  EXPECT_EQ(continued.result.steps, reference.result.steps);
  EXPECT_EQ(history_difference(reference.result.history, continued.result.history), "");
  const std::size_t before = first.states[0].frames_written;
  ASSERT_EQ(before + continued.frames.size(), reference.frames.size());
  for (std::size_t f = 0; f < continued.frames.size(); ++f)
    EXPECT_EQ(frame_difference(reference.frames[before + f], continued.frames[f]), "");
}

INSTANTIATE_TEST_SUITE_P(
    Runs, CheckpointBitwise,
    ::testing::Values(Case{"disk", R"({"geometry":{"disk":{"radius":9e-5},"target_elements":400},
             "run":{"end_time":2e-8,"output_interval":5e-9,"history_interval":1e-9}})",
                           1},
                      Case{"disk_threads2",
                           R"({"geometry":{"disk":{"radius":9e-5},"target_elements":400},
             "run":{"end_time":2e-8,"output_interval":5e-9,"history_interval":1e-9}})",
                           2},
                      // Damage from the release tension at the rim (~10 ns), updated every
                      // 3 steps: d, H and the staggering's counters must come back too.
                      Case{"disk_damage",
                           R"({"geometry":{"disk":{"radius":9e-5},"target_elements":400},
             "run":{"end_time":2e-8,"output_interval":5e-9,"history_interval":1e-9},
             "damage":{"model":"TALAMINI","update_every":3}})",
                           2},
                      Case{"cylinder_threads2",
                           R"({"geometry":{"cylinder":{"radius":9e-5,"thickness":1.2e-5},
             "target_elements":3000},
             "run":{"end_time":1e-8,"output_interval":2.5e-9,"history_interval":5e-10}})",
                           2}),
    [](const auto& info) { return std::string(info.param.name); });

// --- the file -------------------------------------------------------------------------------

Checkpoint small_checkpoint() {
  const v1::RunSpec spec = normalize_spec(parse_spec_json(
      R"({"geometry":{"disk":{"radius":9e-5},"target_elements":200},"run":{"end_time":3e-9}})"));
  const Problem problem = make_problem(spec);
  const Outcome r = run(problem, make_options(spec), {}, nullptr, true);
  Checkpoint c;
  c.state = r.states.at(0);
  c.header.solver_revision = kSolverRevision;
  c.header.solver_version = "test";
  c.header.spec_json = spec_to_json(spec);
  c.header.mesh_fingerprint = mesh_fingerprint(problem.mesh);
  c.header.segments = {{"frames_000.h5", 1}};
  c.header.frame_times = {0.0};
  c.state.frames_written = 1;
  return c;
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}
std::string error_of(const std::string& path) {
  try {
    read_checkpoint(path);
  } catch (const CheckpointError& e) {
    return e.what();
  }
  return "";
}

TEST(CheckpointFile, RoundTripsEveryField) {
  ScratchDir dir("checkpoint");
  const Checkpoint c = small_checkpoint();
  write_checkpoint(dir.str("a.ckpt"), c);
  EXPECT_FALSE(std::filesystem::exists(dir.str("a.ckpt.tmp")));
  const Checkpoint r = read_checkpoint(dir.str("a.ckpt"));
  EXPECT_EQ(r.header.spec_json, c.header.spec_json);
  EXPECT_EQ(r.header.mesh_fingerprint, c.header.mesh_fingerprint);
  ASSERT_EQ(r.header.segments.size(), 1u);
  EXPECT_EQ(r.header.segments[0].file, "frames_000.h5");
  EXPECT_EQ(r.state.time_s, c.state.time_s);
  EXPECT_EQ(r.state.steps, c.state.steps);
  EXPECT_TRUE(r.state.stopped);
  EXPECT_EQ(history_difference(r.state.history, c.state.history), "");
  ASSERT_EQ(r.state.arrays.size(), c.state.arrays.size());
  // Written again from what was read: byte for byte the same file.
  write_checkpoint(dir.str("b.ckpt"), r);
  EXPECT_EQ(read_bytes(dir.str("a.ckpt")), read_bytes(dir.str("b.ckpt")));
}

TEST(CheckpointFile, RefusesDamageTruncationAndAnotherRevision) {
  ScratchDir dir("checkpoint");
  Checkpoint c = small_checkpoint();
  const std::string path = dir.str("state.ckpt");
  write_checkpoint(path, c);
  const std::string good = read_bytes(path);

  std::string flipped = good;
  flipped[good.size() / 2] ^= 0x10;  // one bit inside the state arrays
  write_bytes(path, flipped);
  EXPECT_NE(error_of(path).find("checksum mismatch"), std::string::npos) << error_of(path);

  for (const std::size_t keep : {good.size() - 1, good.size() / 3, std::size_t{10}}) {
    write_bytes(path, good.substr(0, keep));
    EXPECT_NE(error_of(path).find("truncated"), std::string::npos)
        << keep << ": " << error_of(path);
  }

  std::string other_format = good;
  other_format[12] = 9;  // the u32 format after the magic and the byte-order mark
  write_bytes(path, other_format);
  EXPECT_NE(error_of(path).find("format 9"), std::string::npos) << error_of(path);

  c.header.solver_revision = kSolverRevision - 1;
  write_checkpoint(path, c);  // a well-formed file of an older solver
  const std::string old = error_of(path);
  EXPECT_NE(old.find("solver revision " + std::to_string(kSolverRevision - 1)), std::string::npos)
      << old;
  EXPECT_NE(old.find("this is revision " + std::to_string(kSolverRevision)), std::string::npos);

  write_bytes(path, good);
  EXPECT_EQ(error_of(path), "");
}

TEST(CheckpointFile, TheChecksumDoesNotDependOnHowTheBytesArrive) {
  std::string bytes(1000, '\0');
  for (std::size_t k = 0; k < bytes.size(); ++k) bytes[k] = static_cast<char>(k * 37 + 11);
  CheckpointChecksum whole;
  whole.update(bytes.data(), bytes.size());
  for (const std::size_t cut : {1, 3, 7, 8, 9, 500, 999}) {
    CheckpointChecksum pieces;
    pieces.update(bytes.data(), cut);
    pieces.update(bytes.data() + cut, bytes.size() - cut);
    EXPECT_EQ(pieces.value(), whole.value()) << cut;
  }
  CheckpointChecksum shorter;
  shorter.update(bytes.data(), bytes.size() - 1);
  EXPECT_NE(shorter.value(), whole.value());
}

// --- the result file continued from sealed frames --------------------------------------------

// A run whose result is sealed at checkpoints, abandoned (a crash: no finish), and continued from
// its last checkpoint by a new writer gives the datasets of a result written in one go.
TEST(CheckpointResult, AResultContinuedFromSealedFramesEqualsOneWrittenInOneGo) {
  const v1::RunSpec spec = normalize_spec(parse_spec_json(
      R"({"geometry":{"disk":{"radius":9e-5},"target_elements":400},
          "run":{"end_time":2e-8,"output_interval":2.5e-9,"history_interval":1e-9}})"));
  const Problem problem = make_problem(spec);
  const SolverOptions options = make_options(spec);
  ScratchDir dir("checkpoint");
  const std::string json = spec_to_json(spec);
  auto write_all = [&](const std::string& out, const RunState* resume,
                       const std::vector<ResultWriter::Sealed>& sealed,
                       const std::vector<double>& times, int checkpoint_every_steps,
                       int64_t crash_after_steps) {
    std::unique_ptr<AsyncResultWriter> writer =
        resume ? std::make_unique<AsyncResultWriter>(out, problem.mesh, json, "test", sealed, times)
               : std::make_unique<AsyncResultWriter>(out, problem.mesh, json, "test");
    std::atomic<bool> cancel{false};
    int seals = 0;
    RunControl control;
    control.cancel = &cancel;
    control.on_frame = [&](FieldFrame f) { writer->write_frame(std::move(f)); };
    control.checkpoint_due = [&](const Progress& p) {
      if (p.steps >= crash_after_steps) cancel = true;
      return checkpoint_every_steps > 0 && p.steps % checkpoint_every_steps == 0;
    };
    control.on_checkpoint = [&](const RunState& s) {
      Checkpoint c;
      c.state = s;
      c.header.solver_revision = kSolverRevision;
      char name[32];
      std::snprintf(name, sizeof name, "frames_%03d.h5", seals++);
      writer->checkpoint(std::move(c), out + "/checkpoint/" + name, out + "/checkpoint/state.ckpt",
                         [](const std::string& error) { ASSERT_EQ(error, ""); });
    };
    control.resume = resume;
    std::filesystem::create_directories(out + "/checkpoint");
    const RunResult r = run_simulation(problem, options, control);
    if (r.status == RunStatus::kCancelled) {
      writer->drain();
      return r;  // the writer goes without finish(): a crash as far as the files are concerned
    }
    writer->finish(r.history, summarize(problem, r), true, "");
    return r;
  };
  const RunResult one_go = write_all(dir.str("one_go"), nullptr, {}, {}, 0, 1 << 30);
  ASSERT_EQ(one_go.status, RunStatus::kCompleted);
  ASSERT_GT(one_go.steps, 30);  // 39: the crash below comes before the end
  const RunResult crashed = write_all(dir.str("crashed"), nullptr, {}, {}, 8, 30);
  ASSERT_EQ(crashed.status, RunStatus::kCancelled);
  EXPECT_FALSE(std::filesystem::exists(dir.str("crashed/result.h5")));
  const Checkpoint c = read_checkpoint(dir.str("crashed/checkpoint/state.ckpt"));
  ASSERT_GE(c.header.segments.size(), 2u);  // frames sealed at more than one checkpoint
  std::vector<ResultWriter::Sealed> sealed;
  for (const auto& s : c.header.segments)
    sealed.push_back({dir.str("crashed/checkpoint/" + s.file), s.frames});
  const RunResult resumed =
      write_all(dir.str("crashed"), &c.state, sealed, c.header.frame_times, 0, 1 << 30);
  ASSERT_EQ(resumed.status, RunStatus::kCompleted);
  EXPECT_EQ(resumed.steps, one_go.steps);

  const ResultReader a(dir.str("one_go/result.h5")), b(dir.str("crashed/result.h5"));
  EXPECT_TRUE(b.info().complete);
  ASSERT_EQ(a.info().frame_times.size(), b.info().frame_times.size());
  EXPECT_TRUE(same_bits(a.info().frame_times, b.info().frame_times));
  EXPECT_TRUE(same_bits(a.mesh().x, b.mesh().x));
  for (std::size_t f = 0; f < a.info().frame_times.size(); ++f)
    for (const char* name : {"displacement", "velocity", "J", "mean_stress", "radial_stress",
                             "hoop_stress", "von_mises", "aspect_ratio"})
      EXPECT_TRUE(same_bits(a.field(f, name), b.field(f, name))) << "frame " << f << " " << name;
  for (const auto& name : a.series_names())
    EXPECT_TRUE(same_bits(a.series(name), b.series(name))) << name;
  std::size_t ra = 0, ca = 0, rb = 0, cb = 0;
  EXPECT_TRUE(same_bits(a.mode_amplitudes(ra, ca), b.mode_amplitudes(rb, cb)));

  // A sealed file gone: the continuation refuses to start rather than lose frames.
  std::filesystem::remove(sealed[1].path);
  EXPECT_THROW(
      ResultWriter(dir.str("again"), problem.mesh, json, "test", sealed, c.header.frame_times),
      std::runtime_error);
}

}  // namespace
}  // namespace softshock
