// Fixture for tests/module_graph: the program includes of the tools only the demo's interface.
#include "tools/sim/scene.h"
