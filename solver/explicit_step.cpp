#include "explicit_step.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <utility>

namespace softshock {

namespace {

// The largest predicted volume change of any loaded element in one step while the load acts (a
// fraction; LULESH's volume-change limit per step, dvovmax, is 0.1 too). See next_step().
constexpr double kLoadStepVolumeChange = 0.1;

double seconds_between(std::chrono::steady_clock::time_point a,
                       std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// The loaded facets: the problem's, else (load_all_boundary) every boundary facet.
const std::vector<std::array<int32_t, 2>>& loaded_facets(const Problem& p, const Tri3*) {
  return p.loaded_edges.empty() && p.load_all_boundary ? p.mesh.boundary_edges : p.loaded_edges;
}
const std::vector<std::array<int32_t, 3>>& loaded_facets(const Problem& p, const Tet4*) {
  return p.loaded_faces.empty() && p.load_all_boundary ? p.mesh.boundary_faces : p.loaded_faces;
}

// The polar frame's origin of the seeded perturbation (2-D: polar_frame's; 3-D: the axis).
std::array<double, 2> perturbation_origin(const Problem& p, const Tri3*) {
  return polar_frame(p).origin;
}
std::array<double, 2> perturbation_origin(const Problem& p, const Tet4*) {
  if (p.reference_radius_m > 0) return p.origin;
  const auto c = tet_mesh_centroid(p.mesh);
  return {c[0], c[1]};
}

}  // namespace

template <class Element>
ExplicitStep<Element>::ExplicitStep(const Problem& problem, const SolverOptions& options)
    : problem_(problem),
      nn_(problem.mesh.node_count()),
      ne_(problem.mesh.element_count()),
      threads_(options.threads),
      cfl_with_mass_(options.cfl * Element::mass_blend_step_factor(problem.element.mass_blend)),
      geometry_(Element::build_geometry(problem.mesh)),
      pulse_end_(problem.load.end_s()),
      mass_blend_(problem.element.mass_blend),
      nodal_(problem.element.formulation == ElementFormulation::kAverageNodalPressure),
      beta_kappa_(problem.element.stabilization * problem.material.bulk_modulus_Pa),
      w_nodal_(1.0 - problem.element.element_weight) {
  const Mesh& mesh = problem.mesh;
  const std::size_t nn = nn_;
  state_.resize(ne_);

  // Lumped (row-sum) mass: rho0 V_e / (nodes per element) to each corner.
  nodes_.mass.assign(nn, 0.0);
  constexpr double kCorners = Element::kNodes;
  for (std::size_t e = 0; e < ne_; ++e)
    for (int k = 0; k < Element::kNodes; ++k)
      nodes_.mass[Element::corners(geometry_, k)[e]] +=
          problem.material.density_kg_m3 * Element::reference_measure(geometry_, e) / kCorners;

  const std::array<const std::vector<double>*, 3> reference = {&mesh.x, &mesh.y, &mesh.z};
  const std::array<const std::vector<double>*, 3> initial_v = {
      &problem.initial_vx, &problem.initial_vy, &problem.initial_vz};
  const std::array<const std::vector<uint8_t>*, 3> fixed = {&problem.fixed_x, &problem.fixed_y,
                                                            &problem.fixed_z};
  for (int c = 0; c < kDim; ++c) {
    nodes_.x[c] = *reference[c];
    nodes_.v[c].assign(nn, 0.0);
    nodes_.a[c].assign(nn, 0.0);
    if (!initial_v[c]->empty()) nodes_.v[c] = *initial_v[c];
    nodes_.free[c].assign(nn, 1);
    nodes_.fext[c].assign(nn, 0.0);
  }
  for (std::size_t i = 0; i < nn; ++i)
    for (int c = 0; c < kDim; ++c)
      if (!fixed[c]->empty() && (*fixed[c])[i]) nodes_.free[c][i] = 0, nodes_.v[c][i] = 0;
  rows_.resize(nn);
  force_.resize(nn);

  // With a mass blend: the blended mass's momentum (its kinetic energy) and the last forces.
  if (mass_blend_ > 0) {
    for (int c = 0; c < kDim; ++c) nodes_.p[c].resize(nn), nodes_.fprev[c].assign(nn, 0.0);
    blend_weight_ = Element::consistent_mass_weights(geometry_, problem.material.density_kg_m3);
    Element::blended_momentum(geometry_, blend_weight_.data(), mass_blend_, nodes_);
  }

  // The follower pressure: loaded facets and the nodes they touch.
  loaded_facets_ = loaded_facets(problem, static_cast<const Element*>(nullptr));
  for (const auto& f : loaded_facets_)
    loaded_nodes_.insert(loaded_nodes_.end(), f.begin(), f.end());
  std::sort(loaded_nodes_.begin(), loaded_nodes_.end());
  loaded_nodes_.erase(std::unique(loaded_nodes_.begin(), loaded_nodes_.end()), loaded_nodes_.end());
  // Seeded perturbation: each loaded facet's pressure times 1 + amplitude cos(mode theta), theta
  // the reference polar angle of its centroid (2-D: the edge's midpoint).
  facet_factor_.assign(loaded_facets_.size(), 1.0);
  if (problem.perturbation.amplitude != 0.0) {
    const auto origin = perturbation_origin(problem, static_cast<const Element*>(nullptr));
    for (std::size_t k = 0; k < loaded_facets_.size(); ++k) {
      const auto& f = loaded_facets_[k];
      double cx = 0, cy = 0;
      for (int32_t i : f) cx += mesh.x[i], cy += mesh.y[i];
      const double share = 1.0 / static_cast<double>(f.size());  // 2-D: 0.5 (x_a + x_b), as before
      const double theta = std::atan2(share * cy - origin[1], share * cx - origin[0]);
      facet_factor_[k] +=
          problem.perturbation.amplitude * std::cos(problem.perturbation.mode * theta);
    }
  }
  for (int c = 0; c < kDim; ++c) {
    x_old_[c].resize(loaded_nodes_.size());
    fext_old_[c].resize(loaded_nodes_.size());
  }
  loaded_elements_ = Element::elements_on_nodes(geometry_, loaded_nodes_, nn);

  params_.kappa = problem.material.bulk_modulus_Pa;
  params_.tait_n = problem.material.tait_n();
  params_.mu = problem.material.shear_modulus_Pa;
  params_.rho0 = problem.material.density_kg_m3;
  params_.c1 = problem.viscosity.c1;
  params_.c2 = problem.viscosity.c2;
  params_.viscosity = problem.viscosity.enabled;
  const bool thesis_switch = problem.viscosity.switch_kind == ViscositySwitch::kCompressionOnly;
  params_.ramp_inv = thesis_switch ? 1e300 : 1.0 / problem.viscosity.ramp;
  params_.altitude_length = thesis_switch ? 1.0 : 0.0;
  params_.artificial_shear = thesis_switch ? 1.0 : 0.0;
  params_.eta = problem.material.shear_viscosity_Pa_s;

  // Average nodal pressure: nodal volumes, each node's Tait state, then the stabilisation of the
  // element-level volume modes, before the element loop (nodal_pressure.hpp); the last nodal
  // pass writes each node's state into its row beside the position the predictor wrote.
  const std::size_t nodal_n = nodal_ ? nn : 0, nodal_e = nodal_ ? ne_ : 0;
  if (nodal_) nodal_measure0_ = Element::reference_nodal_measures(geometry_, nn);
  for (auto* v : {&nodal_measure_, &nodal_j_, &nodal_sm_, &nodal_k_, &nodal_q_}) v->resize(nodal_n);
  j_element_.resize(nodal_e);
  s_element_.assign(nodal_e, 0.0);
  thread_measure_.resize(nodal_ && threads_ > 1 ? threads_ : 0);
  thread_q_.resize(nodal_ && threads_ > 1 ? threads_ : 0);
  for (auto* v : {&thread_measure_, &thread_q_})
    for (auto& a : *v) a.resize(nn);
  if (nodal_) {
    params_.nodal_pressure = true;
    params_.element_stress_shift = s_element_.data();
    params_.element_weight = problem.element.element_weight;
    params_.stabilization_beta_kappa = beta_kappa_;
  }
  partial_.resize(threads_);
  pass_seconds_.resize(threads_);
  if (problem.damage.enabled())
    damage_ = std::make_unique<damage::DamagePass<kDim>>(problem,
                                                         nodal_ ? nodal_measure0_.data() : nullptr);
  thread_force_.resize(threads_ > 1 ? threads_ : 0);
  for (auto& f : thread_force_) f.resize(nn);
}

template <class Element>
std::pair<std::size_t, std::size_t> ExplicitStep<Element>::node_range(int tid) const {
  return {nn_ * tid / threads_, nn_ * (tid + 1) / threads_};
}

template <class Element>
std::pair<std::size_t, std::size_t> ExplicitStep<Element>::element_range(int tid) const {
  return {ne_ * tid / threads_, ne_ * (tid + 1) / threads_};
}

template <class Element>
template <typename Value>
void ExplicitStep<Element>::sum_threads(std::vector<std::vector<Value>>& parts, std::size_t n0,
                                        std::size_t n1, Value* out) const {
  for (std::size_t i = n0; i < n1; ++i) {
    Value sum{};
    for (int k = 0; k < threads_; ++k) sum += parts[k][i], parts[k][i] = Value{};
    out[i] = sum;
  }
}

// On a sample, passes 2 and 3 also sum the stored energy they see, per thread.
template <class Element>
StoredEnergySum ExplicitStep<Element>::energy_sum(int tid) {
  return sample_ ? StoredEnergySum{w_nodal_, &partial_[tid].nodal_energy} : StoredEnergySum{};
}

template <class Element>
void ExplicitStep<Element>::predict(int tid) {
  const auto [n0, n1] = node_range(tid);
  Element::predict(dt_, n0, n1, nodes_, rows_.data());
}

template <class Element>
void ExplicitStep<Element>::apply_follower_pressure(double t) {
  for (int32_t i : loaded_nodes_)
    for (int c = 0; c < kDim; ++c) nodes_.fext[c][i] = 0.0;
  const double p = problem_.load.at(t);
  if (p == 0.0) return;
  for (std::size_t k = 0; k < loaded_facets_.size(); ++k)
    Element::add_follower_pressure(loaded_facets_[k], p * facet_factor_[k], nodes_, nodes_.fext);
}

template <class Element>
void ExplicitStep<Element>::nodal_volumes(int tid) {  // pass 1: this thread's elements' shares
  const auto [e0, e1] = element_range(tid);
  double* out = threads_ > 1 ? thread_measure_[tid].data() : nodal_measure_.data();
  if (threads_ == 1) std::fill(out, out + nn_, 0.0);  // else cleared by sum_threads
  Element::nodal_measures(geometry_, rows_.data(), e0, e1, out, j_element_.data());
}

template <class Element>
void ExplicitStep<Element>::nodal_state(int tid) {  // pass 2: J, mean stress, bulk modulus
  const auto [n0, n1] = node_range(tid);
  if (threads_ > 1) sum_threads(thread_measure_, n0, n1, nodal_measure_.data());
  nodal_tait_state(params_.kappa, params_.tait_n, nodal_measure0_.data(), nodal_measure_.data(), n0,
                   n1, nodal_j_.data(), nodal_sm_.data(), nodal_k_.data(), energy_sum(tid));
}

template <class Element>
void ExplicitStep<Element>::degraded_nodal_state(int tid) {  // pass 2, after the damage update
  const auto [n0, n1] = node_range(tid);
  if (damage_)  // the damaged nodes' tension, before anything reads the nodal stress
    damage_->degrade_nodal_stress(n0, n1, nodal_j_.data(), nodal_sm_.data(),
                                  sample_ ? &partial_[tid].nodal_energy : nullptr);
  if (beta_kappa_ <= 0)
    Element::pack_nodal_state(nodal_sm_.data(), nodal_k_.data(), n0, n1, rows_.data());
}

// The damage, staggered: every N_d steps, at the predicted configuration the step's forces are
// evaluated at (and, with the average nodal pressure, its nodal J), so that they see the
// degradation of that configuration. The dissipation stays first order in the interval N_d dt
// (docs/verification.md, "The update's interval"): reading the start of the step instead moved it
// by 0.2 % at most.
template <class Element>
void ExplicitStep<Element>::update_damage() {
  const auto start = Clock::now();
  damage_->update(positions(), nodal_ ? nodal_j_.data() : nullptr);
  damage_seconds_ += seconds_between(start, Clock::now());
}

template <class Element>
void ExplicitStep<Element>::stabilization(int tid) {  // pass 3: element discrepancies
  const auto [e0, e1] = element_range(tid);
  double* out = threads_ > 1 ? thread_q_[tid].data() : nodal_q_.data();
  if (threads_ == 1) std::fill(out, out + nn_, 0.0);  // else cleared by sum_threads
  Element::stabilization(geometry_, beta_kappa_, nodal_j_.data(), j_element_.data(), e0, e1,
                         s_element_.data(), out, energy_sum(tid));
}

template <class Element>
void ExplicitStep<Element>::stabilized_state(int tid) {  // pass 4: less the patch mean of s
  const auto [n0, n1] = node_range(tid);
  if (threads_ > 1) sum_threads(thread_q_, n0, n1, nodal_q_.data());
  Element::subtract_stabilization(nodal_measure0_.data(), nodal_q_.data(), nodal_k_.data(), n0, n1,
                                  nodal_sm_.data(), rows_.data());
}

template <class Element>
void ExplicitStep<Element>::element_forces(int tid) {
  const auto [e0, e1] = element_range(tid);
  Force* out = threads_ > 1 ? thread_force_[tid].data() : force_.data();
  if (threads_ == 1) std::fill(out, out + nn_, Force{});  // else cleared by correct
  Element::element_forces(geometry_, rows_.data(), params_, e0, e1, state_, partial_[tid], out);
  if (damage_)  // the damaged elements' degraded share of what the loop just added
    damage_->add_forces(e0, e1, positions(), out,
                        sample_ ? &partial_[tid].element_energy : nullptr);
}

template <class Element>
typename ExplicitStep<Element>::Positions ExplicitStep<Element>::positions() const {
  Positions x;
  for (int c = 0; c < kDim; ++c) x[c] = nodes_.x[c].data();
  return x;
}

template <class Element>
void ExplicitStep<Element>::correct(int tid) {  // a+ = M^-1 f; v+ = v* + dt/2 a+
  const auto [n0, n1] = node_range(tid);
  if (threads_ > 1) sum_threads(thread_force_, n0, n1, force_.data());
  // With a mass blend the velocities wait for the corrected accelerations (mass_blend_correct).
  if (mass_blend_ > 0)
    Element::correct_blended(dt_, n0, n1, force_.data(), nodes_);
  else
    Element::correct(dt_, n0, n1, force_.data(), nodes_);
}

// The mass blend (integrator.hpp): an element pass over the lumped accelerations, summed in the
// force arrays (free again once the accelerations are made), then the node correction.
template <class Element>
void ExplicitStep<Element>::mass_blend_difference(int tid) {
  const auto [e0, e1] = element_range(tid);
  Force* out = threads_ > 1 ? thread_force_[tid].data() : force_.data();
  if (threads_ == 1) std::fill(out, out + nn_, Force{});  // else cleared by sum_threads
  Element::mass_difference(geometry_, blend_weight_.data(), nodes_, e0, e1, out);
}

template <class Element>
void ExplicitStep<Element>::mass_blend_correct(int tid) {
  const auto [n0, n1] = node_range(tid);
  if (threads_ > 1) sum_threads(thread_force_, n0, n1, force_.data());
  Element::correct_mass_blend(dt_, mass_blend_, n0, n1, force_.data(), nodes_);
}

template <class Element>
KernelTotals ExplicitStep<Element>::evaluate(double t, double dt, bool sample) {
  // This step counts towards the damage's interval; the update, when due, runs inside it.
  bool damage_due = false;
  if (damage_ && dt > 0) damage_->advance(dt), damage_due = damage_->due();
  dt_ = dt, sample_ = sample;
  params_.dt = dt, params_.sample = sample;
  std::fill(partial_.begin(), partial_.end(), KernelTotals{});  // each thread's sums of this step
  if (threads_ == 1) {
    // The passes back to back: one clock read between two (~30 ns; a pass takes ~5-170 us at
    // 16.5k triangles).
    auto& seconds = pass_seconds_[0];
    auto last = Clock::now();
    auto lap = [&](StepPass pass) {
      const auto now = Clock::now();
      seconds[static_cast<std::size_t>(pass)] += seconds_between(last, now);
      last = now;
    };
    predict(0), apply_follower_pressure(t), lap(StepPass::kPredictAndLoad);
    auto damage_update = [&] {  // its own clock (damage_seconds), outside the passes' laps
      if (damage_due) update_damage(), last = Clock::now();
    };
    if (nodal_) {
      nodal_volumes(0), lap(StepPass::kNodalAreas);
      nodal_state(0), lap(StepPass::kNodalState);
      damage_update();
      degraded_nodal_state(0), lap(StepPass::kNodalState);
      if (beta_kappa_ > 0) {
        stabilization(0), lap(StepPass::kStabilization);
        stabilized_state(0), lap(StepPass::kStabilizedState);
      }
    } else {
      damage_update();
    }
    element_forces(0), lap(StepPass::kElementForces);
    correct(0), lap(StepPass::kCorrect);
    if (mass_blend_ > 0) {
      mass_blend_difference(0), lap(StepPass::kMassBlendDifference);
      mass_blend_correct(0), lap(StepPass::kMassBlendCorrect);
    }
  } else {
    // Each pass timed on its own, so that the barrier waits between passes are left out.
    auto timed = [&](int tid, StepPass pass, auto&& run_pass) {
      const auto start = Clock::now();
      run_pass();
      pass_seconds_[tid][static_cast<std::size_t>(pass)] += seconds_between(start, Clock::now());
    };
#pragma omp parallel num_threads(threads_)
    {
      const int tid = omp_get_thread_num();
      timed(tid, StepPass::kPredictAndLoad, [&] { predict(tid); });
#pragma omp barrier
      // The follower pressure (boundary facets only) on one thread; the single's barrier follows.
#pragma omp single
      timed(tid, StepPass::kPredictAndLoad, [&] { apply_follower_pressure(t); });
      if (!nodal_ && damage_due) {
#pragma omp single
        update_damage();
      }
      if (nodal_) {
        timed(tid, StepPass::kNodalAreas, [&] { nodal_volumes(tid); });
#pragma omp barrier
        timed(tid, StepPass::kNodalState, [&] { nodal_state(tid); });
        if (damage_due) {  // every node's J first; the single's barrier before the degradation
#pragma omp barrier
#pragma omp single
          update_damage();
        }
        timed(tid, StepPass::kNodalState, [&] { degraded_nodal_state(tid); });
#pragma omp barrier
        if (beta_kappa_ > 0) {
          timed(tid, StepPass::kStabilization, [&] { stabilization(tid); });
#pragma omp barrier
          timed(tid, StepPass::kStabilizedState, [&] { stabilized_state(tid); });
#pragma omp barrier
        }
      }
      timed(tid, StepPass::kElementForces, [&] { element_forces(tid); });
#pragma omp barrier
      timed(tid, StepPass::kCorrect, [&] { correct(tid); });
      if (mass_blend_ > 0) {
#pragma omp barrier
        timed(tid, StepPass::kMassBlendDifference, [&] { mass_blend_difference(tid); });
#pragma omp barrier
        timed(tid, StepPass::kMassBlendCorrect, [&] { mass_blend_correct(tid); });
      }
    }
  }
  KernelTotals total;
  for (const auto& k : partial_) {
    if (k.min_step_sq < total.min_step_sq)
      total.min_step_sq = k.min_step_sq, total.min_step_element = k.min_step_element;
    total.dissipation += k.dissipation;
    total.element_energy += k.element_energy;
    total.nodal_energy += k.nodal_energy;
    total.max_aspect_ratio = std::max(total.max_aspect_ratio, k.max_aspect_ratio);
    if (total.bad_element < 0 && k.bad_element >= 0)
      total.bad_element = k.bad_element, total.bad_j = k.bad_j;
  }
  return total;
}

// While the load acts, every step also keeps the predicted volume change of each element the load
// acts on within kLoadStepVolumeChange. The stable step sees the material's stiffness, not the
// load: the elastic estimate of the first step is taken at rest, and a load at full strength from
// t = 0 (the square pulse) would compress the loaded elements by ~20 % in the first step at cfl
// 0.5 and drive a grid-scale instability at the rim from cfl ~0.7 (P-bar = 1). Bounding the first
// step alone moved that to the next ones: at P-bar = 5 and cfl 0.9 the rim went unstable in the
// second and third steps (A-bar +266 % over 30 ns), at P-bar = 10 and cfl 0.7 +23 %. Those
// elements have a corner on a loaded node; the rest move under internal forces alone, which the
// stable step sees. Over every element the bound gave the same steps (P-bar 1-10, cfl 0.7-0.9) at
// ~20 % of the element loop's cost per step.
template <class Element>
double ExplicitStep<Element>::next_step(double t, KernelTotals& k) const {
  const double dt_elastic = cfl_with_mass_ * std::sqrt(k.min_step_sq);
  if (t >= pulse_end_) return dt_elastic;
  const StepBound bound =
      Element::volume_change_step(geometry_, loaded_elements_, nodes_, kLoadStepVolumeChange);
  if (!(bound.dt_s < dt_elastic)) return dt_elastic;
  k.min_step_element = bound.element;
  return bound.dt_s;
}

template <class Element>
void ExplicitStep<Element>::sample_sums(KernelTotals& totals) const {
  State scratch = state_;
  KernelParams sums_only = params_;
  sums_only.sample = true, sums_only.dt = 0.0;
  KernelTotals sums;
  std::vector<Force> unused(nn_);
  Element::element_forces(geometry_, rows_.data(), sums_only, 0, ne_, scratch, sums, unused.data());
  totals.element_energy = sums.element_energy;
  totals.max_aspect_ratio = sums.max_aspect_ratio;
  if (nodal_)
    totals.nodal_energy =
        Element::nodal_pressure_state(geometry_, nodal_measure0_, params_.kappa, params_.tait_n,
                                      problem_.element.element_weight,
                                      problem_.element.stabilization, nodes_)
            .stored_energy;
  if (damage_)
    totals.element_energy +=
        damage_->stored_energy_correction(positions(), nodal_ ? nodal_j_.data() : nullptr);
}

template <class Element>
void ExplicitStep<Element>::remember_load() {
  for (std::size_t k = 0; k < loaded_nodes_.size(); ++k) {
    const int32_t i = loaded_nodes_[k];
    for (int c = 0; c < kDim; ++c)
      x_old_[c][k] = nodes_.x[c][i], fext_old_[c][k] = nodes_.fext[c][i];
  }
}

template <class Element>
void ExplicitStep<Element>::add_load_work(double& external_work) const {
  for (std::size_t k = 0; k < loaded_nodes_.size(); ++k) {
    const int32_t i = loaded_nodes_[k];
    double w = 0.0;  // + the first product exactly: the 2-D sum is as it always was
    for (int c = 0; c < kDim; ++c)
      w += (fext_old_[c][k] + nodes_.fext[c][i]) * (nodes_.x[c][i] - x_old_[c][k]);
    external_work += 0.5 * w;
  }
}

template <class Element>
KernelView ExplicitStep<Element>::kernel_view() const {
  KernelView view =
      nodal_ ? KernelView{nodal_j_.data(), nodal_sm_.data(), s_element_.data(), j_element_.data()}
             : KernelView{};
  if (damage_) view.element_degradation = damage_->element_degradation();
  return view;
}

template class ExplicitStep<Tri3>;
template class ExplicitStep<Tet4>;

}  // namespace softshock
