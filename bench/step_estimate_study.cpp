// step_estimate_study: the admission's step estimate against the steps the solver takes
// (docs/reliability.md, "Time steps"). Reads lines "NAME SPEC-JSON"
// (bench/step_estimate_cases.txt), runs each spec and prints the steps taken, the estimate from
// the mesh and from the spec, and the estimate's ingredients (dt_load, dt_rest, the passage).
//   build/bench/step_estimate_study bench/step_estimate_cases.txt [--trace DIR]
// --trace DIR also writes DIR/NAME.csv: per history sample the time, the stable step in force
// and the interval's smallest (ns), for fitting the model's factors.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "solver/resource_estimate.hpp"
#include "solver/run_spec.hpp"
#include "solver/simulation.hpp"

int main(int argc, char** argv) {
  const bool trace = argc == 4 && std::string(argv[2]) == "--trace";
  if (argc != 2 && !trace) {
    std::fprintf(stderr, "usage: step_estimate_study CASES.txt [--trace DIR]\n");
    return 2;
  }
  std::ifstream in(argv[1]);
  if (!in) {
    std::fprintf(stderr, "step_estimate_study: cannot read %s\n", argv[1]);
    return 2;
  }
  if (trace && !std::filesystem::is_directory(argv[3])) {
    std::fprintf(stderr, "step_estimate_study: --trace %s: no such folder\n", argv[3]);
    return 2;
  }
  std::printf(
      "| run | elements | steps taken | from the mesh | from the spec | dt_load, dt_rest (ns) | "
      "passage (ns) | status |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  std::string name, json;
  while (in >> name && std::getline(in, json)) {
    using namespace softshock;
    const v1::RunSpec spec = normalize_spec(parse_spec_json(json));
    const Problem problem = make_problem(spec);
    const RunResult result = run_simulation(problem, make_options(spec), RunControl{});
    const double steps = static_cast<double>(result.steps);
    const double from_mesh = estimate_mesh_resources(spec, problem.mesh).steps;
    const double from_spec = estimate_spec_resources(spec).steps;
    const StepEstimate parts = estimate_mesh_steps(spec, problem.mesh);
    std::printf("| %s | %zu | %.0f | %.2fx | %.2fx | %.3f, %.3f | %.1f | %s |\n", name.c_str(),
                problem.mesh.element_count(), steps, from_mesh / steps, from_spec / steps,
                parts.dt_load_s * 1e9, parts.dt_rest_s * 1e9, parts.passage_s * 1e9,
                result.status == RunStatus::kCompleted ? "completed" : result.error.c_str());
    std::fflush(stdout);
    if (trace) {
      const std::string path = std::string(argv[3]) + "/" + name + ".csv";
      std::ofstream csv(path);
      if (!csv) {
        std::fprintf(stderr, "step_estimate_study: cannot write %s\n", path.c_str());
        return 1;
      }
      csv << "# dt_load_ns " << parts.dt_load_s * 1e9 << " dt_rest_ns " << parts.dt_rest_s * 1e9
          << " passage_ns " << parts.passage_s * 1e9 << " steps " << result.steps << "\n";
      csv << "time_ns,dt_ns,min_dt_ns\n";
      const History& h = result.history;
      for (std::size_t i = 0; i < h.size(); ++i)
        csv << h.time[i] * 1e9 << "," << h.dt[i] * 1e9 << "," << h.min_dt[i] * 1e9 << "\n";
    }
  }
  return 0;
}
