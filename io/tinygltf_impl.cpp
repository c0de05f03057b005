// tinygltf's implementation, compiled here without image support: clusterbake never decodes or even
// reads images, and glTF files whose textures are missing still load. The TINYGLTF_NO_* switches are
// set for every io source in CMakeLists.txt, since they change the class layout.
#define TINYGLTF_IMPLEMENTATION
#include <tiny_gltf.h>
