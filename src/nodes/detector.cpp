// The detector as a standalone node: the same class as the nodelet (its own threads serve poses and display).
#include "clod_haptics/ros/haptic_detector.h"
#include "clod_haptics/ros/node_main.h"

int main(int argc, char** argv) { return clod_haptics::runNode<clod_haptics::HapticDetector>(argc, argv, "detector"); }
