#include "server/jobs/admission.hpp"

#include <cmath>
#include <cstdio>
#include <string>

#include "server/byte_size.hpp"
#include "solver/run_spec.hpp"

namespace softshock::server {

namespace {

std::string number(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", x);
  return buf;
}

}  // namespace

void check_admission(const v1::RunSpec& spec, const ResourceEstimate& e,
                     const AdmissionLimits& limits) {
  const auto& r = spec.run();
  // NaN estimates (a degenerate input) are refused too: !(x <= limit).
  if (!(e.steps <= limits.max_steps)) {
    throw SpecError("run.end_time",
                    "the run needs about " + number(e.steps) +
                        " time steps (over run.end_time, at a stable step of about " +
                        number(e.dt_s) +
                        " s, set by the geometry's size "
                        "per geometry.target_elements, the material and load.pressure), more than "
                        "the daemon's max-steps = " +
                        number(limits.max_steps) + ": shorten run.end_time or use larger elements");
  }
  if (!(e.memory_bytes <= limits.max_memory_bytes)) {
    const double samples = std::floor(r.end_time() / r.history_interval()) + 1;
    throw SpecError(
        "run.history_interval",
        "the run needs about " + byte_size(e.memory_bytes) +
            " of memory (its mesh and "
            "state, and " +
            number(samples) + " history samples of " + std::to_string(r.modes() + 13) +
            " values each, from run.end_time / "
            "run.history_interval and run.modes), more than the daemon's max-job-memory "
            "= " +
            byte_size(limits.max_memory_bytes) +
            ": raise run.history_interval, lower run.modes or geometry.target_elements");
  }
  if (!(e.disk_bytes <= limits.max_disk_bytes)) {
    throw SpecError("run.output_interval",
                    "the result file and the state kept for ExtendJob would take about " +
                        byte_size(e.disk_bytes) +
                        " (field frames "
                        "every run.output_interval over run.end_time, each sized by "
                        "geometry.target_elements), more than the daemon's max-job-disk = " +
                        byte_size(limits.max_disk_bytes) +
                        ": raise run.output_interval (0 = no frames) or lower "
                        "geometry.target_elements");
  }
}

void check_spec_admission(const v1::RunSpec& spec, const AdmissionLimits& limits) {
  const ResourceEstimate e = estimate_spec_resources(spec);
  if (std::isnan(e.steps)) return;  // mesh_file: at start, with the mesh
  check_admission(spec, e, limits);
}

}  // namespace softshock::server
