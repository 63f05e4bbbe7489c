// The start-up check of the instruction set the build is for (CMakeLists.txt, CHROMASIM_ARCH).
// Compiled for the compiler's baseline, without the build's -march, and run as a constructor
// of priority 101, before any static initialiser compiled with it: a build for x86-64-v3 on a
// CPU without AVX2 stops here with what to do, instead of dying of SIGILL somewhere later.
// Linked into every executable (chromasim and the test programs).
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace {

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
__attribute__((constructor(101))) void chromasim_check_cpu() {
    // Only the fixed levels can be checked by name; `native` and `portable` are this CPU's.
    if (std::strcmp(CHROMASIM_ARCH, "x86-64-v3") != 0) return;
    __builtin_cpu_init();
#if defined(__clang__) // clang 14 knows no level names: the features that matter here
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
        __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2"))
        return;
#else
    if (__builtin_cpu_supports("x86-64-v3")) return;
#endif
    std::fputs("chromasim: this build is for x86-64-v3 CPUs (AVX2, FMA, BMI2: Intel Haswell, "
               "AMD Excavator and later), and this CPU lacks it. Rebuild for any x86-64 with "
               "`cmake --preset release -DCHROMASIM_ARCH=portable` (README, \"Building by "
               "hand\").\n",
               stderr);
    std::_Exit(1);
}
#endif

} // namespace
