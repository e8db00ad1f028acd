#pragma once
// Fixture for tests/module_graph: perception must not include mapping.
#include "mapping/anything.h"
