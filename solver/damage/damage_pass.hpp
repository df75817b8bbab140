// The damage pass of the explicit step (explicit_step.hpp), for triangles (dim 2) and
// tetrahedra (dim 3): the phase-field damage staggered with the mechanics (docs/model.md,
// "Damage"). It holds the nodal damage d, each element's history field H and the degradations,
// and has three parts:
//   update            every N_d mechanical steps, at the step's predicted configuration: the
//                     tension-only driver psi+ per element, H = max(H, <psi+ - thr>),
//                     one implicit damage step (damage_solver.hpp), the new degradations, and the
//                     stored energy that the damage released at that fixed configuration booked
//                     as dissipated (so the energy balance closes with it);
//   degrade_nodal_stress  (average nodal pressure) each damaged node's tensile Tait stress times
//                     g(d_a), in the nodal pass, before the element loop averages it;
//   add_forces        after the element loop, each damaged element's share of the forces that
//                     the degradation takes away: (1 - g_e) V_e P_dev grad N_a (plus, with the
//                     element's own J, its tensile volumetric stress).
// The element loops themselves are untouched: without damage nothing here runs, and with it only
// the damaged nodes and elements cost anything in a step. g_e = g(mean of the element's nodal d)
// (one-point quadrature of the P1 field), g_a = g(d_a).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "solver/damage/damage_model.hpp"
#include "solver/damage/damage_solver.hpp"
#include "solver/model.hpp"
#include "solver/simulation.hpp"

namespace softshock::damage {

// The damaged zone: where d >= this (the history's damaged_volume, the summary's onset).
inline constexpr double kDamagedThreshold = 0.5;

template <int dim>
class DamagePass {
 public:
  using Positions = std::array<const double*, dim>;  // current nodal x, y[, z] (m)

  // nodal_volume0: the average nodal pressure's reference nodal volumes (their stored energy is
  // degraded node by node); null for plain P1.
  DamagePass(const Problem& problem, const double* nodal_volume0);

  // The staggering: advance() at the start of every mechanical step of dt; due() once N_d steps
  // (this one included) have passed since the last update; update() then, with this step's
  // predicted positions -- those its forces are evaluated at.
  void advance(double dt) { ++steps_since_update_, time_since_update_ += dt; }
  bool due() const { return steps_since_update_ >= update_every_; }
  // nodal_j: the average nodal pressure's J_a at these positions (null for plain P1).
  void update(Positions x, const double* nodal_j);

  // Nodes [n0, n1) (average nodal pressure): mean_stress[a] = sigma_m(J_a) on entry, its
  // degraded value on return. energy (non-null on a history sample): the stored energy's
  // correction, -w (1 - g_a) V_a W_vol(J_a) over the damaged nodes in tension, added to *energy.
  void degrade_nodal_stress(std::size_t n0, std::size_t n1, const double* nodal_j,
                            double* mean_stress, double* energy) const;
  // Elements [e0, e1): the degradation's forces added to out (acting on the nodes, as the element
  // loop's), element by element in index order; energy: the elements' stored-energy correction.
  template <class Force>
  void add_forces(std::size_t e0, std::size_t e1, Positions x, Force* out, double* energy) const;
  // Both stored-energy corrections at once, for a sample not taken in a step.
  double stored_energy_correction(Positions x, const double* nodal_j) const;

  // The history's damage series at this sample (History::damage_*).
  void sample(History& history) const;
  const std::vector<double>& damage() const { return d_; }
  // g_e per element (the diagnostics' stresses).
  const double* element_degradation() const { return g_element_.data(); }
  const DamageSolver<dim>& solver() const { return *solver_; }

  // The state a step hands the next, for checkpoints (explicit_step_state.cpp): visit(name,
  // pointer, count) sees each array; on return the counters and the damaged lists are rebuilt
  // from what the visit left (the same values when saving, the checkpoint's when restoring).
  template <class Visit>
  void visit_state(Visit& visit) {
    visit("damage.d", d_.data(), d_.size());
    visit("damage.h", h_.data(), h_.size());
    visit("damage.g_node", g_node_.data(), g_node_.size());
    visit("damage.g_element", g_element_.data(), g_element_.size());
    std::array<double, 4> counters = {static_cast<double>(steps_since_update_), time_since_update_,
                                      dissipated_, static_cast<double>(solves_)};
    visit("damage.counters", counters.data(), counters.size());
    steps_since_update_ = static_cast<int>(counters[0]);
    time_since_update_ = counters[1];
    dissipated_ = counters[2];
    solves_ = static_cast<int>(counters[3]);
    damaged_nodes_.clear();
    for (std::size_t a = 0; a < d_.size(); ++a)
      if (d_[a] > 0) damaged_nodes_.push_back(static_cast<int32_t>(a));
    damaged_elements_.clear();
    for (std::size_t e = 0; e < g_element_.size(); ++e)
      if (g_element_[e] < 1.0) damaged_elements_.push_back(static_cast<int32_t>(e));
  }
  double dissipated() const { return dissipated_; }
  int solves() const { return solves_; }

 private:
  // An element's energy densities (Pa = J/m^3): deviatoric W_dev(F_e), its own tensile
  // volumetric w_element W_vol+(J_e), and its nodes' w_nodal mean W_vol+(J_a).
  struct ElementEnergy {
    double deviatoric, own_tensile, nodal_tensile;
  };
  ElementEnergy element_energy(std::size_t e, Positions x, const double* nodal_tensile) const;

  Coefficients coefficients_;
  double kappa_, tait_n_, mu_;
  double w_element_, w_nodal_;  // the element's own and the nodes' share of the volumetric law
  const double* nodal_volume0_;
  int update_every_;
  std::unique_ptr<DamageSolver<dim>> solver_;
  std::vector<double> d_, h_;  // nodal damage, element history field (Pa)
  std::vector<double> g_node_, g_element_;
  std::vector<int32_t> damaged_nodes_;     // d_a > 0, ascending
  std::vector<int32_t> damaged_elements_;  // g_e < 1, ascending
  std::vector<double> nodal_tensile_;      // scratch: W_vol+(J_a) per node
  int steps_since_update_ = 0;
  double time_since_update_ = 0;
  double dissipated_ = 0;  // the stored energy released by damage so far (J/m, 2-D; J, 3-D)
  int solves_ = 0;
};

extern template class DamagePass<2>;
extern template class DamagePass<3>;

}  // namespace softshock::damage
