// Configure-time check of the core's ROS guard (CMakeLists.txt, CLOD_CORE_NO_ROS_DIR): with the guard first in
// the include path this must fail to compile; CMake stops if it compiles.
#include <ros/ros.h>

int main() { return 0; }
