// Admission control by estimate: a run whose estimated steps, memory or result size exceeds
// the daemon's limits (--max-steps, --max-job-memory, --max-job-disk) is refused before it is
// queued (SubmitJob, every grid point) and again when it starts (then with its real mesh, and
// with limits that may have changed). Errors name the figure, the limit and the spec fields
// that drive it; the estimate itself is solver/resource_estimate.hpp.
#pragma once

#include "softshock/v1/spec.pb.h"
#include "solver/resource_estimate.hpp"

namespace softshock::server {

struct AdmissionLimits {
  double max_steps = 10'000'000;
  double max_memory_bytes = 4.0 * (1ull << 30);
  double max_disk_bytes = 16.0 * (1ull << 30);
};

// Throws SpecError (field = the spec field that most drives the figure) when the estimate
// breaks a limit.
void check_admission(const v1::RunSpec& spec, const ResourceEstimate& estimate,
                     const AdmissionLimits& limits);

// From a normalized spec alone: disk and rounded square with target_elements over the
// geometry's area. A mesh_file spec passes here; it is checked with its mesh when it starts.
void check_spec_admission(const v1::RunSpec& spec, const AdmissionLimits& limits);

}  // namespace softshock::server
