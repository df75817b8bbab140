// softshock-solve --spec SPEC.json --out DIR [--threads N] [--max-elements N] [--max-end-time S]
//                 [--mesh-cache DIR | --no-mesh-cache]
//                 [--checkpoint-dir DIR [--checkpoint-interval SECONDS]]
// Runs one spec, writes DIR/result.h5 + DIR/result.xdmf, prints the JSON summary on stdout.
// Meshes come from a local cache when it has them (solver/mesh_cache.hpp); Gmsh is loaded only
// when a mesh must be built. Frames are written by a writer thread while the solver steps on.
// With --checkpoint-dir the run writes restartable checkpoints there
// (solver/io/checkpoint_folder.hpp) every --checkpoint-interval of wall time and where
// SIGTERM/SIGINT stops it, and the same command run again continues from the last one: a run on a
// cluster node that Slurm preempts, times out or requeues loses at most one interval. The folder
// goes once the run has finished. Exit codes: 0 success, 2 invalid spec or usage, 1 run failure
// (partial file kept, marked incomplete).
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "softshock/version.hpp"
#include "solver/io/async_result_writer.hpp"
#include "solver/io/checkpoint_folder.hpp"
#include "solver/mesh_cache.hpp"
#include "solver/run_spec.hpp"
#include "solver/run_summary.hpp"
#include "solver/simulation.hpp"

namespace {

std::atomic<bool> g_cancel{false};
extern "C" void on_signal(int) {
  g_cancel.store(true);
}

// The usage text: on stdout for --help (exit 0), on stderr after a usage error (exit 2).
int usage(const char* msg) {
  if (msg) std::fprintf(stderr, "softshock-solve: %s\n", msg);
  std::fprintf(
      msg ? stderr : stdout,
      "usage: softshock-solve --spec SPEC.json --out DIR [--threads N] [--quiet]\n"
      "                       [--max-elements N] [--max-end-time SECONDS]\n"
      "                       [--mesh-cache DIR | --no-mesh-cache]\n"
      "                       [--checkpoint-dir DIR [--checkpoint-interval SECONDS]]\n"
      "  SPEC.json  run spec (protobuf JSON of softshock.v1.RunSpec; {} = baseline)\n"
      "  DIR        output directory: result.h5, result.xdmf\n"
      "  --mesh-cache DIR  meshes built once and reused (default $SOFTSHOCK_MESH_CACHE,\n"
      "             else $XDG_CACHE_HOME/softshock/meshes or ~/.cache/softshock/meshes;\n"
      "             SOFTSHOCK_MESH_CACHE=off disables; SOFTSHOCK_MESH_CACHE_BYTES bounds\n"
      "             it, default 512 MiB)\n"
      "  --checkpoint-dir DIR  restartable checkpoints every --checkpoint-interval seconds of\n"
      "             wall time (default 600) and where SIGTERM or SIGINT stops the run; run the\n"
      "             same command again to continue from the last one (bitwise the run that\n"
      "             never stopped); the folder is removed when the run has finished\n"
      "       softshock-solve --help | --version\n"
      "exit codes: 0 success, 2 invalid spec or usage, 1 run failure\n");
  return 2;
}

// Progress on stderr: a redrawn bar on a terminal, a plain line every 10 % otherwise.
class ProgressReporter {
 public:
  explicit ProgressReporter(bool quiet) : quiet_(quiet), tty_(isatty(STDERR_FILENO)) {}
  void operator()(const softshock::Progress& p) {
    if (quiet_) return;
    const auto now = std::chrono::steady_clock::now();
    const double f = p.fraction();
    if (tty_) {
      if (now - last_ < std::chrono::milliseconds(200) && f < 1.0) return;
      last_ = now;
      const int width = 40, filled = static_cast<int>(f * width);
      std::fprintf(stderr, "\r[%.*s%*s] %5.1f%%  t = %7.2f ns  step %lld  dt = %.3g ps ", filled,
                   "########################################", width - filled, "", 100 * f,
                   p.time_s * 1e9, static_cast<long long>(p.steps), p.dt_s * 1e12);
    } else {
      const int decile = static_cast<int>(f * 10 + 1e-9);
      if (decile <= last_decile_) return;
      last_decile_ = decile;
      std::fprintf(stderr, "progress %3d%%  t = %.2f ns  step %lld\n", decile * 10, p.time_s * 1e9,
                   static_cast<long long>(p.steps));
    }
  }
  void done() {
    if (!quiet_ && tty_) std::fprintf(stderr, "\n");
  }

 private:
  bool quiet_, tty_;
  std::chrono::steady_clock::time_point last_{};
  int last_decile_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  std::string spec_path, out_dir;
  int threads = 0;
  bool quiet = false;
  std::string mesh_cache_dir = softshock::default_mesh_cache_dir();
  std::string checkpoint_dir;
  double checkpoint_interval_s = 600;
  softshock::SpecLimits limits;  // a host's (softshockd on Slurm) limits, else the defaults
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* { return i + 1 < argc ? argv[++i] : nullptr; };
    if (a == "--spec") {
      const char* v = value();
      if (!v) return usage("--spec needs a file");
      spec_path = v;
    } else if (a == "--out") {
      const char* v = value();
      if (!v) return usage("--out needs a directory");
      out_dir = v;
    } else if (a == "--threads") {
      const char* v = value();
      if (!v) return usage("--threads needs a number");
      try {
        threads = std::stoi(v);
      } catch (...) {
        return usage("--threads: not a number");
      }
      if (threads < 1) return usage("--threads: must be >= 1");
    } else if (a == "--mesh-cache") {
      const char* v = value();
      if (!v || !*v) return usage("--mesh-cache needs a directory");
      mesh_cache_dir = v;
    } else if (a == "--checkpoint-dir") {
      const char* v = value();
      if (!v || !*v) return usage("--checkpoint-dir needs a directory");
      checkpoint_dir = v;
    } else if (a == "--checkpoint-interval") {
      const char* v = value();
      char* end = nullptr;
      const double x = v ? std::strtod(v, &end) : -1;
      if (!v || end == v || *end != '\0' || !(x > 0) || !std::isfinite(x)) {
        return usage("--checkpoint-interval: expects seconds > 0");
      }
      checkpoint_interval_s = x;
    } else if (a == "--no-mesh-cache") {
      mesh_cache_dir.clear();
    } else if (a == "--max-elements" || a == "--max-end-time") {
      const char* v = value();
      if (!v) return usage((a + " needs a number").c_str());
      char* end = nullptr;
      const double x = std::strtod(v, &end);
      if (end == v || *end != '\0' || !(x > 0) || !std::isfinite(x)) {
        return usage((a + ": expects a number > 0").c_str());
      }
      if (a == "--max-end-time") {
        limits.max_end_time_s = x;
      } else if (x > 2e9) {
        return usage("--max-elements: at most 2000000000");
      } else {
        limits.max_elements = static_cast<int>(x);
      }
    } else if (a == "--quiet") {
      quiet = true;
    } else if (a == "--help" || a == "-h") {
      usage(nullptr);
      return 0;
    } else if (a == "--version") {
      std::printf("softshock-solve %s\n", softshock::kVersion);
      return 0;
    } else {
      return usage(("unknown argument '" + a + "'").c_str());
    }
  }
  if (spec_path.empty() || out_dir.empty()) return usage("--spec and --out are required");

  // A cache that cannot be used costs a re-mesh, never the run.
  std::unique_ptr<softshock::MeshCache> cache;
  if (!mesh_cache_dir.empty()) {
    try {
      cache = std::make_unique<softshock::MeshCache>(mesh_cache_dir,
                                                     softshock::default_mesh_cache_bytes());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "softshock-solve: warning: no mesh cache: %s\n", e.what());
    }
  }

  softshock::v1::RunSpec spec;
  softshock::Problem problem;
  softshock::MeshingReport meshing;
  try {
    spec = softshock::read_spec_file(spec_path);
    if (threads > 0) spec.mutable_run()->set_threads(threads);
    if (!spec.geometry().mesh_id().empty()) {  // else the default disk would silently run
      throw softshock::SpecError("geometry.mesh_id",
                                 "names a mesh uploaded to softshockd; here use mesh_file");
    }
    spec = softshock::normalize_spec(spec, limits);
    problem = softshock::make_problem(spec, limits, cache.get(), &meshing);
    if (!meshing.warning.empty()) {
      std::fprintf(stderr, "softshock-solve: warning: mesh not cached: %s\n",
                   meshing.warning.c_str());
    }
  } catch (const softshock::SpecError& e) {
    std::fprintf(stderr, "softshock-solve: invalid spec: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "softshock-solve: %s\n", e.what());
    return 1;
  }

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  try {
    const std::string spec_json = softshock::spec_to_json(spec);
    const auto options = softshock::make_options(spec);
    // A previous run's checkpoint of this very run: continue from it.
    std::optional<softshock::Checkpoint> resume;
    if (!checkpoint_dir.empty()) {
      std::string why_not;
      resume = softshock::load_checkpoint_folder(checkpoint_dir, spec_json, problem.mesh,
                                                 options.threads, &why_not);
      if (!why_not.empty())
        std::fprintf(stderr, "softshock-solve: checkpoint not used: %s\n", why_not.c_str());
    }
    std::unique_ptr<softshock::AsyncResultWriter> writer_owner;
    if (resume) {
      try {
        writer_owner = std::make_unique<softshock::AsyncResultWriter>(
            out_dir, problem.mesh, spec_json, SOFTSHOCK_VERSION,
            softshock::checkpoint_segments(checkpoint_dir, resume->header),
            resume->header.frame_times);
      } catch (const std::exception& e) {  // its frame files do not match: from t = 0
        std::fprintf(stderr, "softshock-solve: checkpoint not used: %s\n", e.what());
        resume.reset();
      }
    }
    if (!writer_owner)
      writer_owner = std::make_unique<softshock::AsyncResultWriter>(out_dir, problem.mesh,
                                                                    spec_json, SOFTSHOCK_VERSION);
    softshock::AsyncResultWriter& writer = *writer_owner;
    if (resume)
      std::fprintf(stderr,
                   "softshock-solve: continues from its checkpoint at t = %.6g s, step %lld\n",
                   resume->state.time_s, static_cast<long long>(resume->state.steps));
    ProgressReporter reporter(quiet);
    softshock::RunControl control;
    const std::string fingerprint = softshock::mesh_fingerprint(problem.mesh);
    auto next_checkpoint = std::chrono::steady_clock::now();
    auto take_checkpoint = [&](const softshock::RunState& state) {
      next_checkpoint = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(checkpoint_interval_s));
      std::filesystem::create_directories(checkpoint_dir);
      softshock::write_checkpoint_folder(
          writer, checkpoint_dir, spec_json, fingerprint, state, [](const std::string& error) {
            if (!error.empty())
              std::fprintf(stderr, "softshock-solve: warning: checkpoint not written: %s\n",
                           error.c_str());
          });
    };
    if (!checkpoint_dir.empty()) {
      next_checkpoint += std::chrono::duration_cast<std::chrono::steady_clock::duration>(
          std::chrono::duration<double>(checkpoint_interval_s));
      control.checkpoint_due = [&](const softshock::Progress&) {
        return std::chrono::steady_clock::now() >= next_checkpoint;
      };
      control.checkpoint_at_stop = true;
      control.on_checkpoint = [&](const softshock::RunState& state) {
        // Where the run stopped: worth keeping only when a signal stopped it.
        if (state.stopped && !g_cancel.load()) return;
        take_checkpoint(state);
      };
      if (resume) control.resume = &resume->state;
    }
    control.cancel = &g_cancel;
    control.on_progress = [&](const softshock::Progress& p) { reporter(p); };
    control.on_frame = [&](softshock::FieldFrame f) { writer.write_frame(std::move(f)); };
    control.spare_frame = [&] { return writer.spare_frame(); };
    const auto result = softshock::run_simulation(problem, options, control);
    reporter.done();
    auto summary = softshock::summarize(problem, result);
    summary.meshing_time_s = meshing.seconds;
    summary.mesh_cache = softshock::to_string(meshing.cache);
    const bool complete = result.status == softshock::RunStatus::kCompleted;
    if (!complete && !checkpoint_dir.empty()) writer.drain();  // the stop's checkpoint, durable
    writer.finish(result.history, summary, complete, result.error);
    std::cout << softshock::summary_to_json(summary) << std::endl;
    if (complete && !checkpoint_dir.empty()) {  // its frames are in the result now
      std::error_code ec;
      std::filesystem::remove_all(checkpoint_dir, ec);
    }
    if (!complete) {
      std::fprintf(stderr, "softshock-solve: run %s: %s (partial result kept in %s)\n",
                   summary.status.c_str(),
                   result.error.empty() ? "interrupted" : result.error.c_str(),
                   writer.h5_path().c_str());
      return 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "softshock-solve: %s\n", e.what());
    return 1;
  }
  return 0;
}
