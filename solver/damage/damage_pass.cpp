#include "solver/damage/damage_pass.hpp"

#include <algorithm>
#include <cmath>

#include "solver/continuum.hpp"
#include "solver/node_layout.hpp"

namespace softshock::damage {

namespace {

namespace cm = continuum;

// F = sum_a x_a (x) grad N_a from the current positions (2-D: the in-plane block).
template <int dim>
cm::Tensor<dim> deformation_gradient(const DamageSolver<dim>& solver, std::size_t e,
                                     const std::array<const double*, dim>& x) {
  cm::Tensor<dim> f{};
  const auto& n = solver.corners()[e];
  for (int a = 0; a <= dim; ++a) {
    const auto& grad = solver.gradient(e, a);
    for (int i = 0; i < dim; ++i)
      for (int j = 0; j < dim; ++j) f[dim * i + j] += x[i][n[a]] * grad[j];
  }
  return f;
}

// The Tait energy W_vol(J), J > 0.
double tait_energy(double kappa, double n, double j) {
  return cm::tait_energy(kappa, n, j, std::exp(-n * std::log(j)));
}

}  // namespace

template <int dim>
DamagePass<dim>::DamagePass(const Problem& problem, const double* nodal_volume0)
    : coefficients_(coefficients(problem.damage)),
      kappa_(problem.material.bulk_modulus_Pa),
      tait_n_(problem.material.tait_n()),
      mu_(problem.material.shear_modulus_Pa),
      w_element_(nodal_volume0 ? problem.element.element_weight : 1.0),
      w_nodal_(1.0 - w_element_),
      nodal_volume0_(nodal_volume0),
      update_every_(std::max(1, problem.damage.update_every)),
      solver_(std::make_unique<DamageSolver<dim>>(problem.mesh, coefficients_,
                                                  problem.damage.linear_solver)) {
  const std::size_t nn = solver_->node_count(), ne = solver_->element_count();
  d_.assign(nn, 0.0);
  g_node_.assign(nn, 1.0);
  h_.assign(ne, 0.0);
  g_element_.assign(ne, 1.0);
  nodal_tensile_.assign(nn, 0.0);
}

template <int dim>
typename DamagePass<dim>::ElementEnergy DamagePass<dim>::element_energy(
    std::size_t e, Positions x, const double* nodal_tensile) const {
  const cm::Tensor<dim> f = deformation_gradient<dim>(*solver_, e, x);
  const double j = cm::det(f);
  ElementEnergy out{cm::neo_hookean_energy(mu_, cm::first_invariant(f), std::cbrt(1.0 / (j * j))),
                    0.0, 0.0};
  if (w_element_ > 0)
    out.own_tensile = w_element_ * tensile_volumetric_energy(tait_energy(kappa_, tait_n_, j), j);
  if (nodal_tensile) {
    double sum = 0.0;
    for (int32_t a : solver_->corners()[e]) sum += nodal_tensile[a];
    out.nodal_tensile = w_nodal_ * sum / (dim + 1);
  }
  return out;
}

template <int dim>
void DamagePass<dim>::update(Positions x, const double* nodal_j) {
  const std::size_t nn = d_.size(), ne = h_.size();
  const double* nodal_tensile = nullptr;
  if (nodal_j) {
    for (std::size_t a = 0; a < nn; ++a)
      nodal_tensile_[a] =  // W_vol+(J_a)
          tensile_volumetric_energy(tait_energy(kappa_, tait_n_, nodal_j[a]), nodal_j[a]);
    nodal_tensile = nodal_tensile_.data();
  }
  // The history field: the largest driving energy so far (irreversible by construction).
  // Each element's energy that the degradation acts on (the element's own): W_dev + w W_vol+(J_e).
  std::vector<double> degradable(ne);
  bool driven = !damaged_nodes_.empty(), grew = false;
  for (std::size_t e = 0; e < ne; ++e) {
    const ElementEnergy w = element_energy(e, x, nodal_tensile);
    degradable[e] = w.deviatoric + w.own_tensile;
    const double psi_plus = w.deviatoric + w.own_tensile + w.nodal_tensile;
    const double h = driving_energy(psi_plus, coefficients_.threshold_Pa);
    grew = grew || h > h_[e];
    h_[e] = std::max(h_[e], h);
    driven = driven || h_[e] > 0;
  }
  const double dt = time_since_update_;
  steps_since_update_ = 0, time_since_update_ = 0;
  // Nothing drives damage and there is none (model 1 below its threshold): d stays 0 exactly.
  if (!driven) return;
  // No H grew and no rate term (zeta = 0): the same system as the last solve, whose projected
  // solution d already is -- the solve would return it again.
  if (!grew && coefficients_.zeta_Pa_s == 0 && solves_ > 0) return;
  solver_->solve(h_, dt, d_);
  ++solves_;

  // The stored energy the new degradations release at this configuration, booked as dissipated:
  // sum_e V_e (g_e - g_e+)(W_dev + w W_vol+(J_e)) + w_nodal sum_a V_a (g_a - g_a+) W_vol+(J_a).
  double released = 0.0;
  damaged_nodes_.clear();
  for (std::size_t a = 0; a < nn; ++a) {
    const double g = degradation(d_[a]);
    if (nodal_tensile)
      released += w_nodal_ * nodal_volume0_[a] * (g_node_[a] - g) * nodal_tensile[a];
    g_node_[a] = g;
    if (d_[a] > 0) damaged_nodes_.push_back(static_cast<int32_t>(a));
  }
  damaged_elements_.clear();
  for (std::size_t e = 0; e < ne; ++e) {
    double mean = 0.0;
    for (int32_t a : solver_->corners()[e]) mean += d_[a];
    const double g = degradation(mean / (dim + 1));
    released += solver_->element_volume(e) * (g_element_[e] - g) * degradable[e];
    g_element_[e] = g;
    if (g < 1.0) damaged_elements_.push_back(static_cast<int32_t>(e));
  }
  dissipated_ += released;
}

template <int dim>
void DamagePass<dim>::degrade_nodal_stress(std::size_t n0, std::size_t n1, const double* nodal_j,
                                           double* mean_stress, double* energy) const {
  const auto first =
      std::lower_bound(damaged_nodes_.begin(), damaged_nodes_.end(), static_cast<int32_t>(n0));
  double correction = 0.0;
  for (auto it = first; it != damaged_nodes_.end() && static_cast<std::size_t>(*it) < n1; ++it) {
    const int32_t a = *it;
    if (!(mean_stress[a] > 0.0)) continue;  // compression (J_a <= 1): not degraded
    mean_stress[a] *= g_node_[a];
    if (energy)
      correction -= w_nodal_ * nodal_volume0_[a] * (1.0 - g_node_[a]) *
                    tait_energy(kappa_, tait_n_, nodal_j[a]);
  }
  if (energy) *energy += correction;
}

template <int dim>
template <class Force>
void DamagePass<dim>::add_forces(std::size_t e0, std::size_t e1, Positions x, Force* out,
                                 double* energy) const {
  const auto first = std::lower_bound(damaged_elements_.begin(), damaged_elements_.end(),
                                      static_cast<int32_t>(e0));
  double correction = 0.0;
  for (auto it = first; it != damaged_elements_.end() && static_cast<std::size_t>(*it) < e1; ++it) {
    const std::size_t e = static_cast<std::size_t>(*it);
    const cm::Tensor<dim> f = deformation_gradient<dim>(*solver_, e, x);
    const cm::Tensor<dim> cof = cm::cofactor(f);
    const double j = cm::det(f), inv_j = 1.0 / j, j_minus_23 = std::cbrt(inv_j * inv_j);
    // The stress the degradation takes away: (1 - g) (P_dev + w <sigma_m(J_e)>+ cof F).
    cm::Tensor<dim> p = cm::elastic_piola_inv_j(f, cof, inv_j, 0.0, mu_, j_minus_23);
    double own_tensile = 0.0;
    if (w_element_ > 0 && j > 1.0) {
      const double j_minus_n = std::exp(-tait_n_ * std::log(j));
      const double sm = cm::tait_mean_stress(kappa_, tait_n_, j_minus_n);
      for (std::size_t k = 0; k < p.size(); ++k) p[k] += w_element_ * sm * cof[k];
      own_tensile = w_element_ * cm::tait_energy(kappa_, tait_n_, j, j_minus_n);
    }
    const double lost = 1.0 - g_element_[e], scale = lost * solver_->element_volume(e);
    const auto& n = solver_->corners()[e];
    for (int a = 0; a <= dim; ++a) {
      const auto& grad = solver_->gradient(e, a);
      for (int i = 0; i < dim; ++i) {
        double v = 0.0;
        for (int k = 0; k < dim; ++k) v += p[dim * i + k] * grad[k];
        out[n[a]].lanes[i] += scale * v;  // the element loop added -V_e P grad N_a
      }
    }
    if (energy)
      correction -=
          scale * (cm::neo_hookean_energy(mu_, cm::first_invariant(f), j_minus_23) + own_tensile);
  }
  if (energy) *energy += correction;
}

template <int dim>
double DamagePass<dim>::stored_energy_correction(Positions x, const double* nodal_j) const {
  double correction = 0.0;
  if (nodal_j) {
    std::vector<double> stress(d_.size(), 0.0);
    for (int32_t a : damaged_nodes_)
      stress[a] = cm::tait_mean_stress(kappa_, tait_n_, std::exp(-tait_n_ * std::log(nodal_j[a])));
    degrade_nodal_stress(0, d_.size(), nodal_j, stress.data(), &correction);
  }
  struct Discard {
    std::array<double, 4> lanes{};
  };
  std::vector<Discard> unused(d_.size());
  add_forces(0, h_.size(), x, unused.data(), &correction);
  return correction;
}

template <int dim>
void DamagePass<dim>::sample(History& h) const {
  double damaged = 0.0, largest = 0.0;
  const auto& volume = solver_->nodal_volume();
  for (int32_t a : damaged_nodes_) {
    if (d_[a] >= kDamagedThreshold) damaged += volume[a];
    largest = std::max(largest, d_[a]);
  }
  h.damaged_volume.push_back(damaged);
  h.max_damage.push_back(largest);
  h.crack_energy.push_back(damaged_nodes_.empty() ? 0.0 : solver_->crack_energy(d_));
  h.damage_dissipation.push_back(dissipated_);
}

template class DamagePass<2>;
template class DamagePass<3>;
template void DamagePass<2>::add_forces<NodeForce>(std::size_t, std::size_t, Positions, NodeForce*,
                                                   double*) const;
template void DamagePass<3>::add_forces<NodeForce3>(std::size_t, std::size_t, Positions,
                                                    NodeForce3*, double*) const;

}  // namespace softshock::damage
