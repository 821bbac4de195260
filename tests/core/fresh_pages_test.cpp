// Large buffers mapped before they are first written (pneuma/core/fresh_pages.h, #50). Oracles:
// the kernel's own account of which pages are mapped (mincore), and std::vector's resize and
// assign for the contents.
#include "pneuma/core/fresh_pages.h"

#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace pneuma::core {
namespace {

// How many of the pages of [data, data + bytes) (a page-aligned mapping) the kernel has mapped.
std::size_t mapped_pages(void* data, std::size_t bytes) {
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  std::vector<unsigned char> resident((bytes + page - 1) / page);
  EXPECT_EQ(mincore(data, bytes, resident.data()), 0);
  std::size_t n = 0;
  for (const unsigned char r : resident) n += r & 1U;
  return n;
}

// Whether this kernel maps pages on request (MADV_POPULATE_WRITE, Linux 5.14): asked of a page
// of its own, so that where it can, every test below expects the pages mapped.
bool kernel_maps_on_request() {
#ifdef MADV_POPULATE_WRITE
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  void* const probe = mmap(nullptr, page, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (probe == MAP_FAILED) return false;
  const bool can = madvise(probe, page, MADV_POPULATE_WRITE) == 0;
  munmap(probe, page);
  return can;
#else
  return false;
#endif
}

TEST(FreshPages, AFreshMappingIsMappedWholeAndReadsZero) {
  constexpr std::size_t kBytes = std::size_t{48} << 20;
  void* const data = mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(data, MAP_FAILED);
  // Small pages only, whatever the machine's transparent huge pages: a huge page would map the
  // partial pages at the ends below together with the whole ones.
  madvise(data, kBytes, MADV_NOHUGEPAGE);
  const auto page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  EXPECT_EQ(mapped_pages(data, kBytes), 0U);  // an anonymous mapping is mapped on first touch
  map_for_writing(data, kBytes);
  // Every page mapped where the kernel can; none where it cannot (as without the call).
  const bool can = kernel_maps_on_request();
  EXPECT_EQ(mapped_pages(data, kBytes), can ? kBytes / page : 0U);
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (std::size_t b = 0; b < kBytes; b += 4093) ASSERT_EQ(bytes[b], 0U) << b;
  // A range that starts and ends inside pages: only the whole pages inside it, never the pages
  // it shares with whatever lies around it.
  void* const other = mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(other, MAP_FAILED);
  madvise(other, kBytes, MADV_NOHUGEPAGE);
  map_for_writing(static_cast<unsigned char*>(other) + 100, kBytes - 200);
  EXPECT_EQ(mapped_pages(other, kBytes), can ? kBytes / page - 2 : 0U);
  EXPECT_EQ(mapped_pages(other, page), 0U);
  EXPECT_EQ(mapped_pages(static_cast<unsigned char*>(other) + kBytes - page, page), 0U);
  munmap(data, kBytes);
  munmap(other, kBytes);
}

TEST(FreshPages, ResizeAndAssignGiveWhatTheVectorsOwnDo) {
  // Sizes below and above the smallest buffer mapped first (a few MB), growing from empty and
  // from a smaller vector (its values kept), and shrinking.
  for (const std::size_t n : {std::size_t{1000}, std::size_t{3} << 20, std::size_t{5} << 20}) {
    std::vector<std::int32_t> mapped, plain;
    for (std::int32_t x = 0; x < 777; ++x) mapped.push_back(3 * x - 5), plain.push_back(3 * x - 5);
    resize_mapped(mapped, n);
    plain.resize(n);
    EXPECT_EQ(mapped, plain);
    resize_mapped(mapped, n / 2);
    plain.resize(n / 2);
    EXPECT_EQ(mapped, plain);

    std::vector<std::uint8_t> a{1, 2, 3}, b{1, 2, 3};
    assign_mapped(a, 4 * n, std::uint8_t{7});
    b.assign(4 * n, std::uint8_t{7});
    EXPECT_EQ(a, b);
    assign_mapped(a, n, std::uint8_t{0});
    b.assign(n, std::uint8_t{0});
    EXPECT_EQ(a, b);
  }
}

}  // namespace
}  // namespace pneuma::core
