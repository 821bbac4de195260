// DeformedSurface's chunk kernel built with -mavx2 (see deformed_surface_kernel.h and
// mesh/CMakeLists.txt); called only when the processor reports AVX2.
#include <immintrin.h>

#include <cstddef>
#include <cstdint>

#include "deformed_surface_internal.h"

namespace pneuma::mesh::detail::avx2 {
namespace kernel {
#include "deformed_surface_kernel.h"
}  // namespace kernel

void run_chunk(const KernelData& d, std::size_t k, double s, double* out, double* scratch, double* sums) {
  kernel::run_chunk(d, k, s, out, scratch, sums);
}

void displace_block(const KernelData& d, std::size_t k, double s, double* out) {
  kernel::displace_block<false>(d, k, s, out, nullptr);
}

}  // namespace pneuma::mesh::detail::avx2
