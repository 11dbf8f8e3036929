#pragma once

#include <type_traits>

#include <Eigen/Core>

namespace clod_haptics {
namespace abi {

/**
 * \brief Defined by the library for the alignment Eigen gave its own fixed-size members when it was compiled
 * (EIGEN_MAX_STATIC_ALIGN_BYTES: 16 with SSE, 32 with AVX, 64 with AVX-512, 0 without).
 *
 * A program compiled with other vector flags than the library (-march=native or -mavx against a library built
 * for plain x86-64) lays out every struct holding a Vec3 or an Isometry3d differently from it, and corrupts the
 * heap when the two exchange one (a crash in a destructor far from the cause: PCL and MoveIt users know it). Each
 * translation unit that includes this header refers to the overload for its own alignment, which the library
 * defines only for its own: a mismatch is a link error naming the alignment the program asked for
 * ("undefined reference to clod_haptics::abi::sameEigenAlignmentAsTheLibrary(std::integral_constant<int, 32>)").
 * Fix: compile the program with the library's flags, or rebuild the library with the program's.
 */
int sameEigenAlignmentAsTheLibrary(std::integral_constant<int, EIGEN_MAX_STATIC_ALIGN_BYTES>);

namespace {
// Emitted in every translation unit (used), so every program that includes the library's headers links the check.
[[maybe_unused]] __attribute__((used)) int (*const kEigenAlignmentCheck)(
    std::integral_constant<int, EIGEN_MAX_STATIC_ALIGN_BYTES>) = &sameEigenAlignmentAsTheLibrary;
}  // namespace

}  // namespace abi
}  // namespace clod_haptics
