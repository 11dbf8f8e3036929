#include "dispatch.h"

#include <atomic>

#include "packet_avx2.h"
#include "packet_baseline.h"

namespace clod_haptics {
namespace detail {

namespace {
std::atomic<bool> avx2Off{false};

constexpr PacketKernels kBaseline{packetChildrenBaseline, nullptr, packetTriangleBaseline};
#if defined(CLOD_PACKET_AVX2)
constexpr PacketKernels kAvx2{packetChildrenAvx2, packetChildrenAvx2f, packetTriangleAvx2};
#endif
}  // namespace

void usePacketAvx2(bool on) { avx2Off = !on; }

bool packetAvx2() {
#if defined(CLOD_PACKET_AVX2)
  static const bool has = __builtin_cpu_supports("avx2");
  return has && !avx2Off.load(std::memory_order_relaxed);
#else
  return false;
#endif
}

const PacketKernels& packetKernels() {
#if defined(CLOD_PACKET_AVX2)
  if (packetAvx2()) return kAvx2;
#endif
  return kBaseline;
}

}  // namespace detail
}  // namespace clod_haptics
