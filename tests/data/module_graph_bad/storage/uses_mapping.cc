// Fixture for tests/module_graph: storage uses only the shared value types, not mapping.
#include "mapping/mapper.h"
