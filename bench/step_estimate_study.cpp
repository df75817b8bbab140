// step_estimate_study: the admission's step estimate against the steps the solver takes
// (docs/reliability.md, "Time steps"). Reads lines "NAME SPEC-JSON"
// (bench/step_estimate_cases.txt), runs each spec and prints the steps taken and the estimate from
// the mesh and from the spec.
//   build/bench/step_estimate_study bench/step_estimate_cases.txt
#include <cstdio>
#include <fstream>
#include <string>

#include "solver/resource_estimate.hpp"
#include "solver/run_spec.hpp"
#include "solver/simulation.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: step_estimate_study CASES.txt\n");
    return 2;
  }
  std::ifstream in(argv[1]);
  if (!in) {
    std::fprintf(stderr, "step_estimate_study: cannot read %s\n", argv[1]);
    return 2;
  }
  std::printf("| run | elements | steps taken | from the mesh | from the spec | status |\n");
  std::printf("|---|---|---|---|---|---|\n");
  std::string name, json;
  while (in >> name && std::getline(in, json)) {
    using namespace softshock;
    const v1::RunSpec spec = normalize_spec(parse_spec_json(json));
    const Problem problem = make_problem(spec);
    const RunResult result = run_simulation(problem, make_options(spec), RunControl{});
    const double steps = static_cast<double>(result.steps);
    const double from_mesh = estimate_mesh_resources(spec, problem.mesh).steps;
    const double from_spec = estimate_spec_resources(spec).steps;
    std::printf("| %s | %zu | %.0f | %.2fx | %.2fx | %s |\n", name.c_str(),
                problem.mesh.element_count(), steps, from_mesh / steps, from_spec / steps,
                result.status == RunStatus::kCompleted ? "completed" : result.error.c_str());
    std::fflush(stdout);
  }
  return 0;
}
