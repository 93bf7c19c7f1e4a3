// vision_component: refgrasp's detector as a DDS component speaking ROS 2's types (--help).
#include "component/cli.h"
#include "tool/tool.h"

int main(int argc, char** argv) {
  refgrasp::tool::RunOptions codes;
  codes.output_failed = 4;  // 3 is a DDS failure
  return refgrasp::tool::run("vision_component", argc, argv, refgrasp::component::runVisionComponent, codes);
}
