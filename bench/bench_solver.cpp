// Solver grind time: nanoseconds per element per step (LS-DYNA's "time per zone cycle"), on the
// default disk (concentric rings, the default element, mass blend and viscosities) of ~16.5k, ~66k
// and ~264k elements, with 1 and 2 element-loop threads; 16.5k lumped, one thread; and 16.5k with
// the DOLFINx peer's physics (plain P1, lumped mass, the thesis's viscosity), one thread. In 3-D
// (GrindTime3D*), the same per tetrahedron-step on the cylinder of the peer's 3-D benchmark.
// Each iteration runs the baseline problem for `kSteps` steps and subtracts a run of
// `kWarm` steps, so meshing and set-up are excluded; diagnostics are off (history every 1 s).
// Beside the grind time, each pass of the step as ns per element-step (pass_*_ns: the passes the
// element runs, RunResult::pass_time_s), so that a change to one pass shows where it acts. And the
// machine's memory bandwidth on one and two threads (BM_StreamTriad), against the node passes'
// scaling.
//   build/bench/bench_solver --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>
#include <time.h>

#include <array>
#include <chrono>
#include <map>
#include <string>
#include <vector>

#include "solver/gmsh_mesher.hpp"
#include "solver/run_spec.hpp"
#include "solver/simulation.hpp"

namespace {

constexpr int kWarm = 5, kSteps = 105;

// The default disk of about `elements` triangles; mass_blend < 0: the default's mass blend.
const softshock::Problem& disk(int elements, double mass_blend = -1) {
  static std::map<std::pair<int, double>, softshock::Problem> cache;
  auto it = cache.find({elements, mass_blend});
  if (it == cache.end()) {
    auto spec = softshock::v1::RunSpec();
    spec.mutable_geometry()->set_target_elements(elements);
    if (mass_blend >= 0) spec.mutable_element()->set_mass_blend(mass_blend);
    spec = softshock::normalize_spec(spec);
    it = cache.emplace(std::pair{elements, mass_blend}, softshock::make_problem(spec)).first;
  }
  return it->second;
}

struct Seconds {
  double wall, cpu;  // cpu: all threads of the process (robust to a loaded machine at 1 thread)
  std::array<double, softshock::kStepPasses> pass;  // RunResult::pass_time_s
};

double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

Seconds seconds_for(const softshock::Problem& p, int steps, int threads) {
  softshock::SolverOptions o;
  o.end_time_s = 1e-6;
  o.history_interval_s = 1.0;  // no samples inside the measured steps
  o.output_interval_s = 0;
  o.modes = 0;
  o.threads = threads;
  o.max_steps = steps;
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = process_cpu_seconds();
  const auto r = softshock::run_simulation(p, o);
  benchmark::DoNotOptimize(r.steps);
  return {std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
          process_cpu_seconds() - c0, r.pass_time_s};
}

void grind_time(benchmark::State& state, const softshock::Problem& p, int threads) {
  const double element_steps = static_cast<double>(p.mesh.element_count()) * (kSteps - kWarm);
  double wall = 0, cpu = 0;
  std::array<double, softshock::kStepPasses> pass{};
  for (auto _ : state) {
    const Seconds full = seconds_for(p, kSteps, threads), warm = seconds_for(p, kWarm, threads);
    state.SetIterationTime(full.wall - warm.wall);
    wall += full.wall - warm.wall;
    cpu += full.cpu - warm.cpu;
    for (std::size_t k = 0; k < pass.size(); ++k) pass[k] += full.pass[k] - warm.pass[k];
  }
  const double n = element_steps * static_cast<double>(state.iterations());
  state.counters["elements"] = static_cast<double>(p.mesh.element_count());
  state.counters["wall_ns_per_elem_step"] = wall * 1e9 / n;
  state.counters["cpu_ns_per_elem_step"] = cpu * 1e9 / n;
  // Where the step's time goes, pass by pass (the passes the element runs).
  for (std::size_t k = 0; k < pass.size(); ++k)
    if (pass[k] > 0)
      state.counters[std::string("pass_") +
                     softshock::step_pass_name(static_cast<softshock::StepPass>(k)) + "_ns"] =
          pass[k] * 1e9 / n;
}

void BM_GrindTime(benchmark::State& state) {
  grind_time(state, disk(static_cast<int>(state.range(0))), static_cast<int>(state.range(1)));
}
BENCHMARK(BM_GrindTime)
    ->ArgsProduct({{16500, 66000, 264000}, {1, 2}})
    ->ArgNames({"target_elements", "threads"})
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

// The same with the lumped mass (element.mass_blend 0, the default before 2026-12-02 evening):
// what the default's mass blend costs per element-step.
void BM_GrindTimeLumped(benchmark::State& state) {
  grind_time(state, disk(static_cast<int>(state.range(0)), 0.0), 1);
}
BENCHMARK(BM_GrindTimeLumped)
    ->Arg(16500)
    ->ArgName("target_elements")
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

// The physics of the DOLFINx peer's "full" step (../shared/peer_dolfinx/README.md) as near as the
// spec's options come: plain P1 (one J per triangle), the lumped mass, the thesis's artificial
// viscosity (on while compressing, smallest-altitude length) and no Kelvin-Voigt viscosity. What
// our kernel costs on the peer's own work, beside the default element's (BM_GrindTime).
const softshock::Problem& peer_physics_disk(int elements) {
  static std::map<int, softshock::Problem> cache;
  auto it = cache.find(elements);
  if (it == cache.end()) {
    auto spec = softshock::v1::RunSpec();
    spec.mutable_geometry()->set_target_elements(elements);
    spec.mutable_element()->set_formulation(softshock::v1::P1);
    spec.mutable_element()->set_mass_blend(0.0);
    spec.mutable_viscosity()->set_activation(softshock::v1::COMPRESSION_ONLY);
    spec.mutable_material()->set_shear_viscosity(0.0);
    spec = softshock::normalize_spec(spec);
    it = cache.emplace(elements, softshock::make_problem(spec)).first;
  }
  return it->second;
}
void BM_GrindTimePeerPhysics(benchmark::State& state) {
  grind_time(state, peer_physics_disk(static_cast<int>(state.range(0))), 1);
}
BENCHMARK(BM_GrindTimePeerPhysics)
    ->Arg(16500)
    ->ArgName("target_elements")
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

// 3-D: the spec's cylinder (geometry.cylinder, the default CONCENTRIC_RINGS mesher: the ring disk
// extruded in layers) of R = 90 um and thickness 20 um, the DOLFINx peer's cyl_100k / cyl_400k
// (../shared/peer_dolfinx/README.md, "3-D"), with the default physics (average nodal pressure and
// its stabilisation, mass blend, continuous artificial viscosity, Kelvin-Voigt); counters per
// tetrahedron-step. peer_physics: plain P1, lumped mass, the thesis's viscosity, no Kelvin-Voigt,
// as BM_GrindTimePeerPhysics in 2-D.
const softshock::Problem& cylinder(int elements, bool peer_physics = false) {
  static std::map<std::pair<int, bool>, softshock::Problem> cache;
  auto it = cache.find({elements, peer_physics});
  if (it == cache.end()) {
    auto spec = softshock::v1::RunSpec();
    auto* g = spec.mutable_geometry();
    g->mutable_cylinder()->set_radius(90e-6);
    g->mutable_cylinder()->set_thickness(20e-6);
    g->set_target_elements(elements);
    if (peer_physics) {
      spec.mutable_element()->set_formulation(softshock::v1::P1);
      spec.mutable_element()->set_mass_blend(0.0);
      spec.mutable_viscosity()->set_activation(softshock::v1::COMPRESSION_ONLY);
      spec.mutable_material()->set_shear_viscosity(0.0);
    }
    spec = softshock::normalize_spec(spec);
    it = cache.emplace(std::pair{elements, peer_physics}, softshock::make_problem(spec)).first;
  }
  return it->second;
}
void BM_GrindTime3D(benchmark::State& state) {
  grind_time(state, cylinder(static_cast<int>(state.range(0))), static_cast<int>(state.range(1)));
}
BENCHMARK(BM_GrindTime3D)
    ->Args({100000, 1})
    ->Args({400000, 1})
    ->Args({400000, 2})
    ->ArgNames({"target_elements", "threads"})
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);
void BM_GrindTime3DPeerPhysics(benchmark::State& state) {
  grind_time(state, cylinder(static_cast<int>(state.range(0)), true),
             static_cast<int>(state.range(1)));
}
BENCHMARK(BM_GrindTime3DPeerPhysics)
    ->Args({100000, 1})
    ->ArgNames({"target_elements", "threads"})
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

// The machine's memory bandwidth for one and two threads: STREAM's triad a = b + s c over three
// arrays of doubles (bytes counted as STREAM does: 24 per index, the write-allocate read not
// counted), the indices split in two halves as the step's node passes split the nodes. Whether two
// threads stream twice what one does bounds how those passes scale: at 264k elements one step's
// node rows and nodal arrays take ~13 MB (docs/performance.md, "Pass by pass").
void BM_StreamTriad(benchmark::State& state) {
  const auto n = static_cast<std::ptrdiff_t>(state.range(0) * 1024 * 1024 / (3 * sizeof(double)));
  const int threads = static_cast<int>(state.range(1));
  // Filled on this thread: the VM has one NUMA node (lscpu), so where pages land does not matter.
  std::vector<double> a(n, 0.0), b(n, 1.0), c(n, 2.0);
  for (auto _ : state) {
#pragma omp parallel for num_threads(threads) schedule(static)
    for (std::ptrdiff_t i = 0; i < n; ++i) a[i] = b[i] + 0.5 * c[i];
    benchmark::DoNotOptimize(a.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(state.iterations() * n * 3 * static_cast<int64_t>(sizeof(double)));
}
BENCHMARK(BM_StreamTriad)
    ->ArgsProduct({{1, 4, 16, 64, 256}, {1, 2}})
    ->ArgNames({"MiB", "threads"})
    ->UseRealTime();

// Wall time of the full baseline run (800 ns, diagnostics every 1 ns, no field output).
void BM_BaselineRun(benchmark::State& state) {
  auto spec =
      softshock::normalize_spec(softshock::parse_spec_json(R"({"run":{"output_interval":0}})"));
  const auto& p = disk(16500);
  int64_t steps = 0;
  for (auto _ : state) {
    const auto r = softshock::run_simulation(p, softshock::make_options(spec));
    steps = r.steps;
  }
  state.counters["steps"] = static_cast<double>(steps);
}
BENCHMARK(BM_BaselineRun)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
