// glibc's libmvec has vector variants of exp, log and cbrt; its headers announce them only under
// -ffast-math, which would also assume no NaN and defeat the inversion checks. Declaring the
// variants here lets the branch-free loops (element kernels, nodal passes, frame fields)
// vectorise with IEEE semantics otherwise intact. Call them as ::exp, ::log, ::cbrt.
#pragma once

extern "C" {
__attribute__((simd("notinbranch"))) double exp(double) noexcept;
__attribute__((simd("notinbranch"))) double log(double) noexcept;
__attribute__((simd("notinbranch"))) double cbrt(double) noexcept;
}
