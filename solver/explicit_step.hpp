// One step of the explicit central-difference integrator over one element type (Tri3 or Tet4,
// element_traits.hpp), as a small class whose named passes are StepPass's list, in order
// (docs/model.md, "Time integration"; docs/performance.md, "Pass by pass"):
//   predict_and_load   x+ = x + dt v + dt^2/2 a, v* = v + dt/2 a; the follower pressure at x+
//   nodal_volumes      average nodal pressure, pass 1 (elements): current nodal areas/volumes
//   nodal_state        pass 2 (nodes): J_a, the Tait mean stress and bulk modulus
//   stabilization      pass 3 (elements): the element-volume modes' stabilisation
//   stabilized_state   pass 4 (nodes): the nodal stress less its patch mean, into the node rows
//   element_forces     the element loop: stress, viscosity, nodal forces, stable step
//   correct            a+ = M^-1 f, v+ = v* + dt/2 a+
//   mass_blend_*       the mass blend's element pass and node correction
// With phase-field damage (Problem::damage, damage/damage_pass.hpp) the damage is updated every
// N_d steps at the predicted configuration (after the predictor and, with the nodal pressure, the
// nodal J), the nodal state then degrades the damaged nodes' tension, and the element forces take
// off the damaged elements' degraded share; without it none of that runs.
// With threads, each owns a fixed range of nodes and of elements and adds its elements'
// contributions into its own nodal arrays, summed in thread order: results depend on the thread
// count only. The run loop (simulation.cpp) calls evaluate() once a step.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

#include "damage/damage_pass.hpp"
#include "element_traits.hpp"
#include "model.hpp"
#include "run_state.hpp"
#include "simulation.hpp"

namespace softshock {

template <class Element>
class ExplicitStep {
 public:
  static constexpr int kDim = Element::kDim;
  using Geometry = typename Element::Geometry;
  using State = typename Element::State;
  using Row = typename Element::Row;
  using Force = typename Element::Force;
  using Facet = typename Element::Facet;

  ExplicitStep(const Problem& problem, const SolverOptions& options);

  // The passes in order: the predictor moves the nodes by dt (0: evaluate at the current state),
  // then the forces at the new positions and the corrector. `sample`: the kernel also sums the
  // stored energy and finds the largest aspect ratio.
  KernelTotals evaluate(double t, double dt, bool sample);
  // The step after an evaluation at time t: cfl times the elements' stable step, bounded while
  // the load acts by the loaded elements' predicted volume change; the element that sets it is
  // recorded in k (the history's dt_element).
  double next_step(double t, KernelTotals& k) const;
  // The sample sums (stored energy, largest aspect ratio) of the current state without a step:
  // for a last sample that did not follow a sampling evaluation.
  void sample_sums(KernelTotals& totals) const;
  // The follower load's work over the step just taken, booked as the integrator sees it (the
  // loaded nodes' forces times their displacement increments, trapezoidal in time):
  // remember_load() before evaluate(), add_load_work() after.
  void remember_load();
  void add_load_work(double& external_work) const;

  const Geometry& geometry() const { return geometry_; }
  const State& state() const { return state_; }
  auto view() const { return Element::view(nodes_, mass_blend_ > 0); }
  KernelView kernel_view() const;
  double pulse_end_s() const { return pulse_end_; }
  // Each pass's seconds so far, per thread (RunResult::pass_time_s); reset_pass_times() after
  // the evaluation at t = 0, so that only steps count.
  const std::vector<std::array<double, kStepPasses>>& pass_seconds() const { return pass_seconds_; }
  void reset_pass_times() { pass_seconds_.assign(threads_, {}); }
  // The state one step hands the next (run_state.hpp), as named arrays (explicit_step_state.cpp):
  // save_state appends them; restore_state puts them back, throwing std::invalid_argument that
  // names an array missing or of another size.
  void save_state(std::vector<StateArray>& out) const;
  void restore_state(const std::vector<StateArray>& in);
  // The phase-field damage (null without it) and the wall time of its updates so far.
  const damage::DamagePass<kDim>* damage() const { return damage_.get(); }
  double damage_seconds() const { return damage_seconds_; }

 private:
  using Clock = std::chrono::steady_clock;
  // Calls visit(name, data, count) for each array of the state (double or float data).
  template <class Visit>
  void visit_state(Visit&& visit);
  std::pair<std::size_t, std::size_t> node_range(int tid) const;
  std::pair<std::size_t, std::size_t> element_range(int tid) const;
  // Per-thread partial nodal sums into `out`, added in thread order over the node range, each
  // cleared for the next step's sums while in cache.
  template <typename Value>
  void sum_threads(std::vector<std::vector<Value>>& parts, std::size_t n0, std::size_t n1,
                   Value* out) const;
  StoredEnergySum energy_sum(int tid);

  // The passes (tid: the thread's ranges; one thread: the whole).
  void predict(int tid);
  void apply_follower_pressure(double t);
  void nodal_volumes(int tid);
  void nodal_state(int tid);
  void degraded_nodal_state(int tid);
  void update_damage();
  void stabilization(int tid);
  void stabilized_state(int tid);
  void element_forces(int tid);
  void correct(int tid);
  void mass_blend_difference(int tid);
  void mass_blend_correct(int tid);
  using Positions = std::array<const double*, kDim>;  // damage::DamagePass<kDim>::Positions
  Positions positions() const;

  const Problem& problem_;
  const std::size_t nn_, ne_;
  const int threads_;
  const double cfl_with_mass_;
  Geometry geometry_;
  State state_;
  NodalArrays<kDim> nodes_;
  std::vector<Row> rows_;  // the element passes' rows: position (+ nodal state)
  std::vector<Force> force_;
  // The follower pressure: loaded facets, their seeded-perturbation factors, the nodes they
  // touch, and those nodes' state before the step (for the work).
  std::vector<Facet> loaded_facets_;
  std::vector<double> facet_factor_;
  std::vector<int32_t> loaded_nodes_;
  std::vector<int32_t> loaded_elements_;
  NodalVector<kDim> x_old_, fext_old_;
  double pulse_end_;
  // The mass blend.
  const double mass_blend_;
  std::vector<double> blend_weight_;
  // The element parameters and the average nodal pressure's arrays.
  KernelParams params_;
  const bool nodal_;
  const double beta_kappa_, w_nodal_;
  std::vector<double> nodal_measure0_, nodal_measure_, nodal_j_, nodal_sm_, nodal_k_, nodal_q_;
  std::vector<double> j_element_, s_element_;
  std::vector<std::vector<double>> thread_measure_, thread_q_;
  std::vector<std::vector<Force>> thread_force_;
  std::vector<KernelTotals> partial_;
  std::vector<std::array<double, kStepPasses>> pass_seconds_;
  std::unique_ptr<damage::DamagePass<kDim>> damage_;
  double damage_seconds_ = 0;
  // The step being evaluated.
  double dt_ = 0;
  bool sample_ = false;
};

extern template class ExplicitStep<Tri3>;
extern template class ExplicitStep<Tet4>;

}  // namespace softshock
