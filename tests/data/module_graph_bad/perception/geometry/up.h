#pragma once
// Fixture for tests/module_graph: the shared value types include nothing of perception above them.
#include "perception/obstacle_detector.h"
