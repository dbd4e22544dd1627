// OpenGL 3.3 core for the viewer: the entry points (GLFW's headers with the extension prototypes)
// and shader programs built or refused by name.
#pragma once

#define GL_GLEXT_PROTOTYPES
#define GLFW_INCLUDE_GLEXT
#include <GLFW/glfw3.h>

#include "mesh/scene.h"

namespace penumbra::gl {

// A shader program from its vertex and fragment sources. Throws Error with the driver's log when it
// rejects one.
GLuint program(const char* vertex, const char* fragment);

// The camera's view and perspective projection for a width x height target, its near and far
// planes from the scene's size.
Eigen::Matrix4f viewProjection(const Camera& c, int width, int height, double sceneSize);

}  // namespace penumbra::gl
