// vision_component: refgrasp's detector as a DDS component speaking ROS 2's types (--help).
#include "component/cli.h"

int main(int argc, char** argv) { return refgrasp::component::runVisionComponent(argc, argv); }
