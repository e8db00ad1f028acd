#pragma once
// Fixture for tests/module_graph: sqlite3 must stay out of public headers.
#include <sqlite3.h>
