// tinygltf's implementation, in a library of its own (photorig_tinygltf):
// the files that use it compile faster, and the fuzz build, which
// instruments photorig_daemon_io, leaves this third-party JSON code plain
// (its coverage would only slow the glTF round-trip target).
#define TINYGLTF_IMPLEMENTATION
#include "tinygltf_config.h"
