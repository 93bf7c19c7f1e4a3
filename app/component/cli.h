#pragma once
// The vision_component command line; app/vision_component.cpp runs it through tool::run (one line
// and the documented exit code for any exception).
namespace refgrasp::component {

/// Parses the options, loads the objects, serves until SIGINT or SIGTERM, prints the run's
/// statistics as one JSON line on stdout. Exit status: 0 after a clean shutdown; 2 for bad
/// options or files (one line on stderr naming the file and field); 3 when DDS cannot start
/// (e.g. a bad CYCLONEDDS_URI).
int runVisionComponent(int argc, char** argv);

}  // namespace refgrasp::component
