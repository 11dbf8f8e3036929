#pragma once
// Test control of the fake libHD (test/device/fake_libhd/fake_hd.cpp): what a test does to the "hardware"
// (move the stylus, press buttons, inject errors, unplug it, ask for calibration) and what it reads back
// (the force the servo loop last sent). Thread-safe; callable while the scheduler runs.
//
// A process that cannot call these (a node under rostest) configures its devices at hdInitDevice from the
// environment:
//   CLOD_FAKE_HD_CALIBRATION   ok | update | manual   (initial hdCheckCalibration answer; default ok)
//   CLOD_FAKE_HD_UNPLUG_AFTER_MS  N                   (the device is unplugged N ms after hdInitDevice)
//   CLOD_FAKE_HD_ERROR         0xCODE[:persistent]    (an error injected at hdInitDevice)
//   CLOD_FAKE_HD_POSITION      x,y,z                  (stylus position, device frame, millimetres)
//   CLOD_FAKE_HD_PATH          x0,y0,z0,x1,y1,z1,T    (the stylus goes from the first point to the second and back
//                                                      every T seconds, millimetres)
//   CLOD_FAKE_HD_NOMINAL_FORCES  peak,continuous      (HD_NOMINAL_MAX_FORCE, ..._CONTINUOUS_FORCE, newtons)

#include <HD/hd.h>

#ifdef __cplusplus
extern "C" {
#endif

/** \brief The handle of an initialised device by its name ("" or NULL: the default device); HD_INVALID_HANDLE if none.
 */
HHD fakeHdFindDevice(const char* name);
/** \brief Stylus transform, column-major 4x4 as HD_CURRENT_TRANSFORM, translation in millimetres. */
void fakeHdSetTransform(HHD device, const double transform[16]);
/** \brief Stylus position (device frame, millimetres), keeping the rotation. */
void fakeHdSetPosition(HHD device, double x, double y, double z);
/** \brief Stylus velocity (device frame, mm/s) as HD_CURRENT_VELOCITY reports it. */
void fakeHdSetVelocity(HHD device, double vx, double vy, double vz);
/** \brief HD_CURRENT_JOINT_ANGLES and HD_CURRENT_GIMBAL_ANGLES, radians. */
void fakeHdSetAngles(HHD device, const double joints[3], const double gimbal[3]);
/** \brief HD_CURRENT_BUTTONS bits. */
void fakeHdSetButtons(HHD device, int buttons);
/** \brief The force the last completed frame sent to the motors (device frame, N); zero while force output is off. */
void fakeHdLastForce(HHD device, double force[3]);
/** \brief Frames completed on the device (hdEndFrame of an outermost frame). */
unsigned long fakeHdFrames(HHD device);
/**
 * \brief Makes every frame from now on report `code` at hdEndFrame (persistent) or only the next one.
 * HD_SUCCESS clears a persistent error.
 */
void fakeHdInjectError(HHD device, HDerror code, int persistent);
/** \brief Unplugs the device: every frame reports HD_COMM_ERROR and returns the last values read before. */
void fakeHdUnplug(HHD device);
/** \brief hdCheckCalibration's answer from now on, and the HD_CALIBRATION_STYLE bits the device supports. */
void fakeHdSetCalibration(HHD device, HDenum status, int styles);
/** \brief The stylus put in (1) or taken out of (0) the inkwell: NEEDS_MANUAL_INPUT becomes NEEDS_UPDATE. */
void fakeHdSetInkwell(HHD device, int inInkwell);
/** \brief Times hdUpdateCalibration changed the calibration. */
unsigned long fakeHdCalibrationUpdates(HHD device);
/** \brief HD_NOMINAL_MAX_FORCE and HD_NOMINAL_MAX_CONTINUOUS_FORCE, newtons (default 3.3 and 0.88). */
void fakeHdSetNominalForces(HHD device, double peak, double continuous);
/** \brief Forgets every device (the scheduler must be stopped): the next test starts from power-up. */
void fakeHdReset(void);

#ifdef __cplusplus
}
#endif
