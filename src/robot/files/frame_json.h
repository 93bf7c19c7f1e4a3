#pragma once
// JSON for what a frame carries (capture state, ground truth, robot state), as written in a
// recording's index.jsonl. Poses through core/json.h: {"R": [9 numbers, row-major], "t": [x, y, z]}
// (aMb, metres), the detect_object convention. Doubles are written with the shortest text that
// reads back to the same bits, so write -> read -> write gives identical lines.
#include <string>
#include <vector>

#include "core/json.h"
#include "core/pose.h"
#include "robot/camera.h"
#include "robot/hal.h"

namespace refgrasp::files {

Json captureToJson(const robot::CaptureState& c);
Json truthToJson(const std::vector<robot::ObjectTruth>& truth);
Json robotStateToJson(const robot::RobotState& s);

// Readers: false and a problem "<field>: <what is wrong>" when the JSON does not fit.
bool captureFromJson(const Json& j, robot::CaptureState* c, std::string* problem);
bool truthFromJson(const Json& j, std::vector<robot::ObjectTruth>* truth, std::string* problem);
bool robotStateFromJson(const Json& j, robot::RobotState* s, std::string* problem);

}  // namespace refgrasp::files
