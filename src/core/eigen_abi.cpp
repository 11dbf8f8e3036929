#include "clod_haptics/core/eigen_abi.h"

namespace clod_haptics {
namespace abi {

int sameEigenAlignmentAsTheLibrary(std::integral_constant<int, EIGEN_MAX_STATIC_ALIGN_BYTES>) {
  return EIGEN_MAX_STATIC_ALIGN_BYTES;
}

}  // namespace abi
}  // namespace clod_haptics
