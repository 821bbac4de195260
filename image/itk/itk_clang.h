#pragma once
// Debian's ITK 5.2 headers were generated for GCC alone: under clang (the fuzz preset, clang-tidy)
// itk_compiler_detection.h stops with "Unsupported compiler". Clang speaks GCC's dialect, so
// the detection is run once, first, as for GCC 12 (whose C++ features clang 14 has), and the
// compiler's own macros are put back. Included before any ITK header (image/src/itk_read.cpp,
// voxels_itk.cpp: the targets that link pneuma_itk).
#if defined(__clang__)
#pragma clang diagnostic push
#pragma clang diagnostic ignored "-Wbuiltin-macro-redefined"
#pragma push_macro("__clang__")
// NOLINTBEGIN(bugprone-reserved-identifier): the compiler macros ITK checks, set for its header only
#pragma push_macro("__GNUC__")
#pragma push_macro("__GNUC_MINOR__")
#undef __clang__
#undef __GNUC__
#undef __GNUC_MINOR__
#define __GNUC__ 12
#define __GNUC_MINOR__ 2
#include <itk_compiler_detection.h>
#pragma pop_macro("__GNUC_MINOR__")
#pragma pop_macro("__GNUC__")
#pragma pop_macro("__clang__")
// NOLINTEND(bugprone-reserved-identifier)
#pragma clang diagnostic pop
#endif
