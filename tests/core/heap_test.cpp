// keep_large_blocks_in_heap (core/heap.h). Oracle: glibc's own accounting (mallinfo2): a block
// served by a fresh mapping shows in hblkhd, one served by the heap in arena, and a heap that is
// trimmed on free gives the bytes back (arena falls).
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>

#include "pneuma/core/heap.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

// The sanitizer presets (CMakePresets.json) replace glibc's allocator with their own.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define PNEUMA_OWN_ALLOCATOR 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define PNEUMA_OWN_ALLOCATOR 1
#endif
#endif

namespace pneuma {
namespace {

TEST(Heap, LargeBlocksComeFromTheHeapAndStayThere) {
#if !defined(__GLIBC__)
  GTEST_SKIP() << "not glibc: the settings do not exist";
#elif defined(PNEUMA_OWN_ALLOCATOR)
  GTEST_SKIP() << "a sanitizer's allocator serves malloc, not glibc's";
#else
  constexpr std::size_t kBlock = 256u << 20;  // above glibc's largest dynamic threshold (32 MiB)
  ASSERT_TRUE(keep_large_blocks_in_heap());
  const struct mallinfo2 before = mallinfo2();
  void* block = std::malloc(kBlock);
  ASSERT_NE(block, nullptr);
  std::memset(block, 1, kBlock);  // used, so the compiler keeps it
  const struct mallinfo2 held = mallinfo2();
  EXPECT_EQ(held.hblkhd, before.hblkhd) << "the block was a fresh mapping";
  EXPECT_GE(held.arena, before.arena + kBlock);
  std::free(block);
  EXPECT_GE(mallinfo2().arena, before.arena + kBlock) << "the heap was trimmed on free";
#endif
}

}  // namespace
}  // namespace pneuma
