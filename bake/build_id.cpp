// The one translation unit that includes the generated build id (bake/CMakeLists.txt), so that a change to
// any source recompiles this file alone.
#include "bake_file.h"
#include "cb_build_id.h"

namespace cb {

const char* build_id() { return CB_BUILD_ID; }

}  // namespace cb
