// The whole-body scans of a history sample, written like the element kernel (blocks of
// gathered edges, a branch-free vectorised loop, then the reductions in element order), so a
// sample costs about one element-loop pass: the stored energy (J^-2/3 and J^-n from one vector
// log and exp, as the kernel computes them) and the largest aspect ratio.
#pragma once

#include <cstddef>

#include "element_kernels.hpp"

namespace softshock {

struct ElementScan {
  double energy = 0;            // the running sum passed in, plus this scan's terms (J/m)
  double max_aspect_ratio = 0;  // longest edge^2 / (2 area), the first of equal maxima
};

// Adds A_e (W_dev(F_e) + w_element W_vol(J_e)) of every element to `energy`, in element order,
// and finds the largest aspect ratio.
ElementScan scan_elements(const ElementGeometry& geometry, const double* x, const double* y,
                          double mu, double kappa, double tait_n, double w_element, double energy);

// Adds w V_a W_vol(J_a) of every node to `energy`, in node order.
double add_nodal_volumetric_energy(const double* reference_area, const double* nodal_j,
                                   std::size_t nodes, double kappa, double tait_n, double w,
                                   double energy);

}  // namespace softshock
