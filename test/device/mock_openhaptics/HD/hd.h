// A compile-only stand-in for the OpenHaptics HD header: the declarations
// src/device/openhaptics_device.cpp uses, with the SDK's types and signatures (values are not
// the SDK's). CMake compiles the OpenHaptics backend against it when the real SDK is missing,
// so the backend cannot rot unnoticed; it is never linked or run.
#pragma once

typedef unsigned int HHD;
typedef unsigned int HDenum;
typedef unsigned int HDerror;
typedef int HDint;
typedef double HDdouble;
typedef unsigned short HDushort;
typedef const char* HDstring;
typedef unsigned long HDSchedulerHandle;
typedef unsigned int HDCallbackCode;
#define HDCALLBACK
#define HD_CALLBACK_DONE 0
#define HD_CALLBACK_CONTINUE 1
typedef HDCallbackCode(HDCALLBACK* HDSchedulerCallback)(void* pUserData);

#define HD_DEFAULT_DEVICE ((HDstring)0)
#define HD_MAX_SCHEDULER_PRIORITY 0xffff
#define HD_SUCCESS 0x0000
typedef struct {
  HDerror errorCode;
  int internalErrorCode;
  HHD hHD;
} HDErrorInfo;
#define HD_DEVICE_ERROR(X) (((X).errorCode) != HD_SUCCESS)

#define HD_CURRENT_BUTTONS 0x2000
#define HD_CURRENT_TRANSFORM 0x2052
#define HD_CURRENT_JOINT_ANGLES 0x2100
#define HD_CURRENT_GIMBAL_ANGLES 0x2150
#define HD_CURRENT_FORCE 0x2700
#define HD_FORCE_OUTPUT 0x4000
#define HD_DEVICE_BUTTON_1 (1 << 0)
#define HD_DEVICE_BUTTON_2 (1 << 1)

#ifdef __cplusplus
extern "C" {
#endif
HHD hdInitDevice(HDstring pConfigName);
void hdDisableDevice(HHD hHD);
void hdMakeCurrentDevice(HHD hHD);
void hdEnable(HDenum cap);
void hdBeginFrame(HHD hHD);
void hdEndFrame(HHD hHD);
void hdGetDoublev(HDenum pname, HDdouble* params);
void hdGetIntegerv(HDenum pname, HDint* params);
void hdSetDoublev(HDenum pname, const HDdouble* params);
HDErrorInfo hdGetError(void);
HDstring hdGetErrorString(HDerror errorCode);
void hdStartScheduler(void);
void hdStopScheduler(void);
HDSchedulerHandle hdScheduleAsynchronous(HDSchedulerCallback pCallback, void* pUserData, HDushort nPriority);
void hdUnschedule(HDSchedulerHandle hHandle);
HDdouble hdGetSchedulerTimeStamp(void);
#ifdef __cplusplus
}
#endif
