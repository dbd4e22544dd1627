#include "viewer/gl.h"

#include <cmath>

#include "core/error.h"

namespace penumbra::gl {
namespace {

GLuint compile(GLenum type, const char* source) {
    const GLuint s = glCreateShader(type);
    glShaderSource(s, 1, &source, nullptr);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[2048];
        glGetShaderInfoLog(s, sizeof log, nullptr, log);
        throw Error(cat("view: the OpenGL driver rejected a shader: ", log));
    }
    return s;
}

}  // namespace

GLuint program(const char* vertex, const char* fragment) {
    const GLuint p = glCreateProgram();
    glAttachShader(p, compile(GL_VERTEX_SHADER, vertex));
    glAttachShader(p, compile(GL_FRAGMENT_SHADER, fragment));
    glLinkProgram(p);
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) throw Error("view: the OpenGL driver could not link a shader program");
    return p;
}

Eigen::Matrix4f viewProjection(const Camera& c, int width, int height, double sceneSize) {
    const Vec3 f = (c.lookAt - c.position).normalized();
    const Vec3 s = f.cross(c.up).normalized();
    const Vec3 u = s.cross(f);
    Eigen::Matrix4d view = Eigen::Matrix4d::Identity();
    view.row(0) << s.x(), s.y(), s.z(), -s.dot(c.position);
    view.row(1) << u.x(), u.y(), u.z(), -u.dot(c.position);
    view.row(2) << -f.x(), -f.y(), -f.z(), f.dot(c.position);
    const double near = 1e-3 * sceneSize, far = 20 * sceneSize + (c.position - c.lookAt).norm() * 4;
    const double t = 1 / std::tan(c.fovYDeg * kPi / 360), aspect = double(width) / height;
    Eigen::Matrix4d projection = Eigen::Matrix4d::Zero();
    projection(0, 0) = t / aspect;
    projection(1, 1) = t;
    projection(2, 2) = (far + near) / (near - far);
    projection(2, 3) = 2 * far * near / (near - far);
    projection(3, 2) = -1;
    return (projection * view).cast<float>();
}

}  // namespace penumbra::gl
