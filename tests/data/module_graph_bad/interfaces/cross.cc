// Fixture for tests/module_graph: interfaces and storage never include each other.
#include "storage/map_database.h"
