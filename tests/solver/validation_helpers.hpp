// Small helpers shared by the solver validation tests.
#pragma once

#include <cmath>
#include <vector>

#include "solver/model.hpp"
#include "solver/simulation.hpp"

namespace softshock::testing {

// Total energy error of the stored-energy balance, relative to the external work:
// (kinetic + elastic + dissipated - external) / external at sample k.
inline double energy_balance_error(const History& h, std::size_t k) {
  return (h.kinetic_energy[k] + h.elastic_energy[k] + h.dissipated_energy[k] - h.external_work[k]) /
         h.external_work[k];
}

// Times at which a series crosses zero upwards, linearly interpolated.
inline std::vector<double> upward_zero_crossings(const std::vector<double>& t,
                                                 const std::vector<double>& v) {
  std::vector<double> out;
  for (std::size_t k = 1; k < v.size(); ++k)
    if (v[k - 1] < 0 && v[k] >= 0)
      out.push_back(t[k - 1] + (t[k] - t[k - 1]) * (-v[k - 1]) / (v[k] - v[k - 1]));
  return out;
}

}  // namespace softshock::testing
