/* Fake OpenHaptics header for clod_haptics' tests (test/device/fake_libhd): the declarations of the HD API
   as the OpenHaptics 3 Linux SDK lays them out, including its traps, written for this project.
   Export and calling-convention macros. Like the SDK's, they exist only when `linux` (or WIN32 / __APPLE__)
   is defined: GCC defines `linux` in its GNU modes (-std=gnu++17) but not under strict -std=c++17, where
   HDAPI, HDAPIENTRY and HDCALLBACK are then undefined and every declaration fails to compile. On Linux the
   calling convention is the stdcall attribute, which x86-64 GCC ignores with a -Wattributes warning. */
#ifndef HD_EXPORT_H_DEFINE
#define HD_EXPORT_H_DEFINE

#if defined(WIN32)
#define HDAPI __declspec(dllimport)
#define HDAPIENTRY __stdcall
#define HDCALLBACK __stdcall
#endif

#if defined(linux)
#define HDAPI
#define HDAPIENTRY __attribute__((stdcall))
#define HDCALLBACK __attribute__((stdcall))
#endif

#if defined(__APPLE__)
#define HDAPI
#define HDAPIENTRY
#define HDCALLBACK
#endif

#endif /* HD_EXPORT_H_DEFINE */
