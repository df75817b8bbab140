// The per-element hot loop: deformation gradient, Tait + neo-Hookean stress, artificial
// viscosity, nodal forces, stable-step candidate and dissipation increment, over plain
// structure-of-arrays data. No virtual calls, no I/O, no allocation.
#pragma once

#include <cstdint>
#include <vector>

#include "mesh.hpp"
#include "node_layout.hpp"

namespace softshock {

// Reference geometry of the P1 elements (constant during a run).
struct ElementGeometry {
  std::vector<int32_t> node0, node1, node2;
  // Dm^-1 with Dm = [X1 - X0, X2 - X0]; rows are the reference gradients of N1 and N2.
  std::vector<double> dm_inv_xx, dm_inv_xy, dm_inv_yx, dm_inv_yy;
  std::vector<double> area0;  // m^2 (per metre of thickness: m^3/m)
  std::size_t size() const { return area0.size(); }
};

// From a finalized 2-D mesh (built for the baseline ISA: no contraction, the same bits anywhere).
ElementGeometry build_tri3_geometry(const Mesh& mesh);

// Element state carried from one force evaluation to the next.
struct ElementState {
  std::vector<double> f_xx, f_xy, f_yx, f_yy;  // F at the last evaluation (lags the viscosity)
  // Viscous P at the last evaluation and its shear nu and bulk zeta (Pa s), in single precision:
  // the dynamics never read them back (each evaluation computes P_v afresh from F and F_prev,
  // which stay double); only the dissipation's trapezoidal sum and the stress diagnostics do.
  std::vector<float> pv_xx, pv_xy, pv_yx, pv_yy;
  std::vector<float> viscosity, bulk_viscosity;
  void resize(std::size_t elements);
  void reset_to_reference();  // F = I, P_v = 0
};

// nodes[i]'s position lanes = (x[i], y[i]), for i in [begin, end).
void pack_positions(const double* x, const double* y, std::size_t begin, std::size_t end,
                    PackedNode* nodes);
// nodes[i]'s state lanes = (mean_stress[i], bulk_modulus[i]), for i in [begin, end).
void pack_nodal_state(const double* mean_stress, const double* bulk_modulus, std::size_t begin,
                      std::size_t end, PackedNode* nodes);

struct KernelParams {
  double kappa = 0, tait_n = 0, mu = 0, rho0 = 0;
  double c1 = 0, c2 = 0;
  bool viscosity = true;  // artificial viscosity
  // 1 / ramp of the continuous switch (continuum::artificial_viscosity); huge = thesis switch.
  double ramp_inv = 5.0;
  // Length of the artificial viscosity: 1 = smallest altitude (thesis), 0 = sqrt(sqrt(3) area),
  // the altitude of the equilateral triangle of the current area (does not vanish on slivers);
  // one or the other (values above 0.5 select the smallest altitude).
  double altitude_length = 0.0;
  double eta = 0;  // Kelvin-Voigt shear viscosity, Pa s (on whenever dt > 0)
  // 1: the artificial viscosity is a shear viscosity (the thesis); 0: a bulk viscosity 4/3 nu.
  double artificial_shear = 0.0;
  // Average nodal pressure: the nodes' Tait mean stress and bulk modulus (nodal_pressure.hpp,
  // in the PackedNode rows) mixed with the element's own as (1 - w) mean(nodal) + w element.
  // false = plain P1 (w = 1).
  bool nodal_pressure = false;
  // Stabilisation of the nodal-pressure element (nodal_pressure.hpp): per-element stress s_e
  // added to the nodal mean, and its tangent modulus beta kappa - 2 s_e (continuum.hpp) added to
  // the bulk modulus of the stable step.
  const double* element_stress_shift = nullptr;
  double stabilization_beta_kappa = 0.0;
  double element_weight = 1.0;
  double dt = 0;  // the step that led from the stored state to the current positions; 0 = none
  // A history sample follows this evaluation: also sum the elements' stored energy and find
  // their largest aspect ratio (KernelTotals), from the F and J^-2/3 the loop computes anyway.
  bool sample = false;
};

struct KernelTotals {
  double min_step_sq = 1e300;     // min over elements of the stable step squared (s^2)
  int64_t min_step_element = -1;  // the element that sets it
  double dissipation = 0;         // trapezoidal P_v : dF increment over this step (J/m)
  int64_t bad_element = -1;       // first element with J <= 0 or non-finite J
  double bad_j = 0;
  // KernelParams::sample only (else 0): sum_e A_e (W_dev(F_e) + w W_vol(J_e)) in element order,
  // w the element's own weight (0 for the average nodal pressure element, whose W_vol is the
  // nodes'), J/m; and the largest longest-edge^2 / (2 area).
  double element_energy = 0;
  double max_aspect_ratio = 0;
  // Not the element loop's: the nodal-pressure passes' share of the stored energy on a sample
  // evaluation (StoredEnergySum, nodal_pressure.hpp; the integrator adds it to a step's totals).
  double nodal_energy = 0;
};

// Evaluates elements [begin, end): updates their state and adds their nodal forces (acting on
// the nodes, = -f_int) to node_force, element by element in index order — so the sums are
// deterministic for a given element range.
void compute_element_forces(const ElementGeometry& geometry, const PackedNode* nodes,
                            const KernelParams& params, std::size_t begin, std::size_t end,
                            ElementState& state, KernelTotals& totals, NodeForce* node_force);

}  // namespace softshock
