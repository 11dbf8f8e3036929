/* Fake OpenHaptics header (test/device/fake_libhd): compiler configuration. As in the SDK, on Linux it
   defines TRUE, FALSE, Sleep and the function-like macros min(a,b) and max(a,b): after it, std::min(x, y),
   std::max(x, y) and std::numeric_limits<T>::max() no longer compile (or silently become the macro).
   Include it after every C++ header and #undef min and max right after. */
#ifndef HD_COMPILERCONFIG_H_DEFINE
#define HD_COMPILERCONFIG_H_DEFINE

#if defined(linux) || defined(__APPLE__)
#if !defined(TRUE)
#define TRUE 1
#endif
#if !defined(FALSE)
#define FALSE 0
#endif
#if !defined(max)
#define max(a, b) (((a) > (b)) ? (a) : (b))
#endif
#if !defined(min)
#define min(a, b) (((a) < (b)) ? (a) : (b))
#endif
#if !defined(MB_OK)
#define MB_OK 0
#endif
#if !defined(Sleep)
#define Sleep(x) usleep((x)*1000)
#endif
#endif

#endif /* HD_COMPILERCONFIG_H_DEFINE */
