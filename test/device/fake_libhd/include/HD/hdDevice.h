/* Fake OpenHaptics header (test/device/fake_libhd): device, frame, state and calibration calls, declared as
   the SDK declares them (HDAPI ... HDAPIENTRY). */
#ifndef HD_DEVICE_H_DEFINE
#define HD_DEVICE_H_DEFINE

#include <HD/hdExport.h>
#include <HD/hdCompilerConfig.h>
#include <HD/hdDefines.h>

#ifdef __cplusplus
extern "C" {
#endif

HDAPI HHD HDAPIENTRY hdInitDevice(HDstring pConfigName);
HDAPI void HDAPIENTRY hdMakeCurrentDevice(HHD hHD);
HDAPI void HDAPIENTRY hdDisableDevice(HHD hHD);
HDAPI HHD HDAPIENTRY hdGetCurrentDevice();
HDAPI void HDAPIENTRY hdBeginFrame(HHD hHD);
HDAPI void HDAPIENTRY hdEndFrame(HHD hHD);
/* The most recent error first; errorCode HD_SUCCESS when none is left. */
HDAPI HDErrorInfo HDAPIENTRY hdGetError();
#define HD_DEVICE_ERROR(X) (((X).errorCode) != HD_SUCCESS)
HDAPI HDstring HDAPIENTRY hdGetErrorString(HDerror errorCode);
HDAPI void HDAPIENTRY hdEnable(HDenum cap);
HDAPI void HDAPIENTRY hdDisable(HDenum cap);
HDAPI HDboolean HDAPIENTRY hdIsEnabled(HDenum cap);
HDAPI void HDAPIENTRY hdGetBooleanv(HDenum pname, HDboolean* params);
HDAPI void HDAPIENTRY hdGetIntegerv(HDenum pname, HDint* params);
HDAPI void HDAPIENTRY hdGetFloatv(HDenum pname, HDfloat* params);
HDAPI void HDAPIENTRY hdGetDoublev(HDenum pname, HDdouble* params);
HDAPI void HDAPIENTRY hdGetLongv(HDenum pname, HDlong* params);
HDAPI HDstring HDAPIENTRY hdGetString(HDenum pname);
HDAPI void HDAPIENTRY hdSetBooleanv(HDenum pname, const HDboolean* params);
HDAPI void HDAPIENTRY hdSetIntegerv(HDenum pname, const HDint* params);
HDAPI void HDAPIENTRY hdSetFloatv(HDenum pname, const HDfloat* params);
HDAPI void HDAPIENTRY hdSetDoublev(HDenum pname, const HDdouble* params);
HDAPI void HDAPIENTRY hdSetLongv(HDenum pname, const HDlong* params);
HDAPI HDenum HDAPIENTRY hdCheckCalibration();
HDAPI HDenum HDAPIENTRY hdCheckCalibrationStyle();
HDAPI void HDAPIENTRY hdUpdateCalibrationMessage(HDenum style);
HDAPI void HDAPIENTRY hdUpdateCalibration(HDenum style);

#ifdef __cplusplus
}
#endif

#endif /* HD_DEVICE_H_DEFINE */
