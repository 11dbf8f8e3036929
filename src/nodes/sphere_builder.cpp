// sphere_builder node: serves CLOD levels of one mesh (see SphereBuilderNode). Several threads, so that a long
// build does not block requests for cached levels.
#include "clod_haptics/ros/node_main.h"
#include "clod_haptics/ros/sphere_builder_node.h"

int main(int argc, char** argv) {
  return clod_haptics::runNode<clod_haptics::SphereBuilderNode>(argc, argv, "sphere_builder", 4);
}
