#include <cmath>
#include <numbers>

#include "model.hpp"

namespace softshock {

// Shapes (s = t / duration, P = pressure):
//  square:    P on [0, 1], P/2 exactly at s = 1 (a jump takes the mean of its one-sided limits,
//             which makes the trapezoidal impulse of the integrator exact when a step lands
//             on the jump, as the time loop arranges);
//  linear:    triangle rising to P at s = 1/2 and back to 0 at s = 1;
//  quadratic: C1 piecewise-quadratic bell: 8 s^2 on [0, 1/4], 1 - 8 (s - 1/2)^2 on [1/4, 3/4],
//             8 (1 - s)^2 on [3/4, 1];
//  gaussian:  full width at half maximum = duration, centred at 1.5 duration, cut at
//             3 duration (p(0) = P / 512).
double PressurePulse::at(double t) const {
  if (t < 0.0) return 0.0;
  const double s = t / duration_s;
  switch (shape) {
    case PulseShape::kSquare:
      return s < 1.0 ? pressure_Pa : (s == 1.0 ? 0.5 * pressure_Pa : 0.0);
    case PulseShape::kLinear:
      return s <= 1.0 ? pressure_Pa * (1.0 - std::fabs(2.0 * s - 1.0)) : 0.0;
    case PulseShape::kQuadratic:
      if (s <= 0.25) return pressure_Pa * 8.0 * s * s;
      if (s <= 0.75) return pressure_Pa * (1.0 - 8.0 * (s - 0.5) * (s - 0.5));
      if (s <= 1.0) return pressure_Pa * 8.0 * (1.0 - s) * (1.0 - s);
      return 0.0;
    case PulseShape::kGaussian: {
      if (s > 3.0) return 0.0;
      const double z = s - 1.5;  // FWHM 1: exp(-4 ln 2 z^2)
      return pressure_Pa * std::exp(-4.0 * std::numbers::ln2 * z * z);
    }
  }
  return 0.0;
}

double PressurePulse::end_s() const {
  return shape == PulseShape::kGaussian ? 3.0 * duration_s : duration_s;
}

double PressurePulse::impulse_Pa_s() const {
  switch (shape) {
    case PulseShape::kSquare:
      return pressure_Pa * duration_s;
    case PulseShape::kLinear:
    case PulseShape::kQuadratic:
      return 0.5 * pressure_Pa * duration_s;
    case PulseShape::kGaussian:  // sqrt(pi / (4 ln 2)) * erf(3 sqrt(ln 2)) ~ 1 - 2e-4
      return pressure_Pa * duration_s * std::sqrt(std::numbers::pi / (4.0 * std::numbers::ln2)) *
             std::erf(3.0 * std::sqrt(std::numbers::ln2));
  }
  return 0.0;
}

}  // namespace softshock
