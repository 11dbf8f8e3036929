// marker_stylus node: the stylus dragged in RViz (an interactive marker), published at 1 kHz as a device would
// (see MarkerStylus). Two threads: the marker server's feedback and ~goal.
#include "clod_haptics/ros/marker_stylus.h"
#include "clod_haptics/ros/node_main.h"

int main(int argc, char** argv) {
  return clod_haptics::runNode<clod_haptics::MarkerStylus>(argc, argv, "marker_stylus", 2);
}
