#pragma once
// How the process's heap treats large blocks.
namespace pneuma {

// Large blocks (a fine lung's fields, graphs and hulls: tens of MB each) are taken from the heap
// and go back to it when freed, instead of each being a fresh mapping returned to the system on
// free: the kernel zeroes every page of a fresh mapping on first touch, which was 13 % of a
// 1M-vertex field's time (BENCHMARKS.md, #35). The heap is then not trimmed either, so a freed
// block serves the next one. Only the process's peak memory is kept. Returns false where the C
// library has no such settings (not glibc) or refuses them. The CLI calls it once, first thing.
bool keep_large_blocks_in_heap();

}  // namespace pneuma
