#pragma once
// Large buffers mapped before they are first written (#50). A fresh buffer of a native time point
// (0.07-0.85 GB each, 3.6 GB in all at case004's own grid; the label map and the CT as read, image/)
// is mapped by the kernel page by page
// as it is first touched: one fault per 4 KiB page (about 900k a time point), and where a
// std::vector value-initialises it, all of them under one thread's memset while the other core
// waits. Mapping the pages first, in slices from every core, takes the faults' entry costs away
// and shares the zeroing between the cores. The values are what they were: only when the pages
// are mapped changes.
#include <cstddef>
#include <vector>

namespace pneuma::core {

// Asks the kernel to map [data, data + bytes) for writing now (Linux's MADV_POPULATE_WRITE, in
// slices on every core). Does nothing below a few MB, or where the kernel cannot (before Linux
// 5.14, or short of memory): the pages are then mapped on first touch, as without it.
void map_for_writing(void* data, std::size_t bytes);

// v.resize(n), with the pages of a new allocation mapped first (map_for_writing).
template <typename T>
void resize_mapped(std::vector<T>& v, std::size_t n) {
  if (n > v.capacity()) {
    v.reserve(n);
    map_for_writing(v.data(), n * sizeof(T));
  }
  v.resize(n);
}

// v.assign(n, value), with the pages of a new allocation mapped first (map_for_writing).
template <typename T>
void assign_mapped(std::vector<T>& v, std::size_t n, const T& value) {
  if (n > v.capacity()) {
    v.clear();  // nothing to copy into the new block
    v.reserve(n);
    map_for_writing(v.data(), n * sizeof(T));
  }
  v.assign(n, value);
}

}  // namespace pneuma::core
