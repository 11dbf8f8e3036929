#pragma once
// Hashes of raw bytes: the content hashes of the cache keys and the checksum that ends every cache file.

#include <cstddef>
#include <cstdint>

namespace clod_haptics {

/** \brief FNV-1a 64 over raw bytes (64-bit words), continuing from seed: the content hashes of the cache keys. */
std::uint64_t fnv1a64(const void* data, std::size_t bytes, std::uint64_t seed = 0xcbf29ce484222325ull);

/**
 * \brief The checksum at the end of every cache file (mesh, sphere set, grid): four interleaved FNV-1a 64 lanes over
 * 32-byte blocks, then the lanes, the length and the tail. The lanes' multiplications do not wait for each other, so
 * it runs about four times as fast as one lane: a restart checks hundreds of megabytes of grids and meshes.
 */
std::uint64_t cacheChecksum(const void* data, std::size_t bytes);

}  // namespace clod_haptics
