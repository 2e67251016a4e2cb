#pragma once
// tinygltf as the project builds it. Debian's libtinygltf-dev ships the
// header only, without stb: images are written and read by OpenCV, and
// tinygltf only references them by URI.
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>
