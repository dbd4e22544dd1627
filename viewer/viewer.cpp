#include "viewer/viewer.h"

#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>

#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "core/error.h"
#include "core/image_file.h"
#include "core/log.h"
#include "io/export.h"
#include "io/image_io.h"
#include "render/final_gather.h"
#include "render/radiosity_view.h"
#include "viewer/gl.h"
#include "viewer/scene_draw.h"

namespace penumbra {
namespace {

// The float image, tone-mapped as the PNG previews are (clamp(scale * L), then sRGB), or by
// Reinhard's operator on luminance.
const char* kDisplayVertex = R"(#version 330 core
out vec2 uv;
void main() {
    vec2 p = vec2((gl_VertexID == 1) ? 3.0 : -1.0, (gl_VertexID == 2) ? 3.0 : -1.0);
    uv = 0.5 * (p + 1.0);
    gl_Position = vec4(p, 0.0, 1.0);
})";
const char* kDisplayFragment = R"(#version 330 core
in vec2 uv;
uniform sampler2D image;
uniform float scale;
uniform int reinhard;
out vec4 colour;
vec3 srgb(vec3 v) {
    v = clamp(v, 0.0, 1.0);
    return mix(12.92 * v, 1.055 * pow(v, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), v));
}
void main() {
    vec3 v = scale * texture(image, uv).rgb;
    // Reinhard on luminance keeps highlights from clipping; the default clamps like the previews.
    if (reinhard == 1) {
        float l = dot(v, vec3(0.2126, 0.7152, 0.0722));
        v *= 1.0 / (1.0 + l);
    }
    colour = vec4(srgb(v), 1.0);
})";

// Mouse and keyboard navigation about a target point (orbit, pan, zoom) or from the eye (fly).
struct Navigation {
    Camera camera, start;
    bool fly = false, edges = false;
    double lastX = 0, lastY = 0;
    bool dragging = false;

    // Turns `moved` about `pivot`: the eye about the target (orbit) or the target about the eye (fly).
    void rotateAbout(const Vec3& pivot, Vec3& moved, double yaw, double pitch, bool orbit) {
        const Vec3 up = start.up.normalized();
        const Vec3 forward = (camera.lookAt - camera.position).normalized();
        const Vec3 right = forward.cross(up).normalized();
        const Eigen::AngleAxisd turn(yaw, up), tilt(pitch, right);
        Vec3 offset = tilt * (turn * (moved - pivot));
        // Keep away from the poles, where up and the view direction would align.
        const Vec3 dir = orbit ? Vec3(-offset.normalized()) : Vec3(offset.normalized());
        if (std::abs(dir.dot(up)) > 0.995) offset = turn * (moved - pivot);
        moved = pivot + offset;
    }
    void mouse(double x, double y, int button, double sceneSize) {
        const double dx = x - lastX, dy = y - lastY;
        lastX = x, lastY = y;
        if (!dragging) return;
        const Vec3 forward = camera.lookAt - camera.position;
        const Vec3 right = forward.normalized().cross(start.up).normalized();
        const Vec3 up = right.cross(forward.normalized());
        if (fly || button == GLFW_MOUSE_BUTTON_LEFT) {
            if (fly)
                rotateAbout(camera.position, camera.lookAt, -0.004 * dx, -0.004 * dy, false);
            else
                rotateAbout(camera.lookAt, camera.position, -0.006 * dx, -0.006 * dy, true);
        } else {
            const double scale = std::max(forward.norm(), 1e-3 * sceneSize) * 0.0015;
            const Vec3 shift = (-dx * right + dy * up) * scale;
            camera.position += shift;
            camera.lookAt += shift;
        }
    }
    void zoom(double steps) {
        const Vec3 d = camera.position - camera.lookAt;
        camera.position = camera.lookAt + d * std::pow(0.9, steps);
    }
    void move(GLFWwindow* w, double seconds, double sceneSize) {
        if (!fly) return;
        const Vec3 forward = (camera.lookAt - camera.position).normalized();
        const Vec3 right = forward.cross(start.up).normalized();
        Vec3 step = Vec3::Zero();
        if (glfwGetKey(w, GLFW_KEY_W) == GLFW_PRESS) step += forward;
        if (glfwGetKey(w, GLFW_KEY_S) == GLFW_PRESS) step -= forward;
        if (glfwGetKey(w, GLFW_KEY_D) == GLFW_PRESS) step += right;
        if (glfwGetKey(w, GLFW_KEY_A) == GLFW_PRESS) step -= right;
        step *= 0.4 * sceneSize * seconds;
        camera.position += step;
        camera.lookAt += step;
    }
};

// Key presses as events (down now, up at the last look).
struct Keys {
    std::map<int, bool> down;
    bool pressed(GLFWwindow* w, int key) {
        const bool now = glfwGetKey(w, key) == GLFW_PRESS;
        const bool was = down[key];
        down[key] = now;
        return now && !was;
    }
};

// The final-gather render of one view, refined one sample per pixel per pass on a worker thread
// until cancelled; the main thread shows the running mean.
class Progressive {
public:
    Progressive(const Scene& scene, const PatchSet& patches, const CornerValues& corners, const std::vector<Rgb>& means,
                const CornerValues& indirect)
        : scene_(scene), patches_(patches), corners_(corners), means_(means), indirect_(indirect) {}
    ~Progressive() { stop(); }

    void start(const Camera& camera) {
        stop();
        if (!solved_)
            solved_ = std::make_unique<SolvedScene>(scene_, patches_, corners_, GatherSettings{}, PhotonSettings{}, 1,
                                                    nullptr, means_.empty() ? nullptr : &means_, indirect_);
        camera_ = camera;
        cancel_ = false;
        passes_ = 0;
        sum_.assign(size_t(camera.width) * size_t(camera.height) * 3, 0.0);
        worker_ = std::thread([this] {
            for (uint64_t pass = 1; !cancel_; ++pass) {
                const Image image = solved_->render(camera_, 1, pass);
                if (cancel_) break;
                std::lock_guard<std::mutex> lock(mutex_);
                for (size_t k = 0; k < sum_.size(); ++k) sum_[k] += image.rgb[k];
                ++passes_;
            }
        });
    }
    void stop() {
        cancel_ = true;
        if (worker_.joinable()) worker_.join();
    }
    bool running() const { return worker_.joinable(); }
    int passes() const { return passes_; }
    // The mean so far, or an empty image before the first pass.
    Image mean() {
        std::lock_guard<std::mutex> lock(mutex_);
        Image image;
        if (passes_ == 0) return image;
        image = Image(camera_.width, camera_.height);
        for (size_t k = 0; k < sum_.size(); ++k) image.rgb[k] = float(sum_[k] / passes_);
        return image;
    }

private:
    const Scene& scene_;
    const PatchSet& patches_;
    const CornerValues& corners_;
    const std::vector<Rgb>& means_;
    const CornerValues& indirect_;
    std::unique_ptr<SolvedScene> solved_;  // built on the first G
    Camera camera_;
    std::thread worker_;
    std::atomic<bool> cancel_{false};
    std::atomic<int> passes_{0};
    std::mutex mutex_;
    std::vector<double> sum_;
};

// The picture drawn: linear radiance (.exr), or tone-mapped as the previews are (.png).
void saveScreenshot(const Image& image, const ViewerOptions& options) {
    if (lowerExtension(options.screenshot) == ".exr")
        writeLinearImage(image, options.screenshot);
    else
        writePreviewPng(image, options.screenshot, options.exposureStops);
}

bool sameView(const Camera& a, const Camera& b) {
    return a.position == b.position && a.lookAt == b.lookAt && a.width == b.width && a.height == b.height;
}

std::string cameraJson(const Camera& c, double unitScale) {
    auto p = [&](const Vec3& v) {
        return cat("[", v.x() / unitScale, ", ", v.y() / unitScale, ", ", v.z() / unitScale, "]");
    };
    return cat("{\"position\": ", p(c.position), ", \"look_at\": ", p(c.lookAt), ", \"up\": [", c.up.x(), ", ",
               c.up.y(), ", ", c.up.z(), "], \"fov_y_deg\": ", c.fovYDeg, ", \"resolution\": [", c.width, ", ",
               c.height, "]}");
}

}  // namespace

void requireDisplay() {
    const char* x11 = std::getenv("DISPLAY");
    const char* wayland = std::getenv("WAYLAND_DISPLAY");
    if ((!x11 || !*x11) && (!wayland || !*wayland))
        throw Error(
            "view: no display to open a window on (DISPLAY is not set). Headless: `penumbra render SCENE "
            "--solution DIR --integrator radiosity --out IMAGE.exr` (any --camera, or --orbit N), `penumbra "
            "export DIR --out FILE.glb`, or run the viewer under `xvfb-run -a`");
}

void runViewer(const Scene& scene, const PatchSet& patches, const CornerValues& corners, const std::vector<Rgb>& means,
               const CornerValues& indirect, const Camera& start, const ViewerOptions& options) {
    requireDisplay();
    if (!glfwInit()) throw Error("view: GLFW could not start (no usable display)");
    struct Terminate {
        ~Terminate() { glfwTerminate(); }
    } terminate;
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    const bool screenshot = !options.screenshot.empty();
    if (screenshot) glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
    GLFWwindow* window = glfwCreateWindow(start.width, start.height, "penumbra", nullptr, nullptr);
    if (!window) throw Error("view: no OpenGL 3.3 core context could be created on this display");
    glfwMakeContextCurrent(window);
    glfwSwapInterval(screenshot ? 0 : 1);
    const auto glText = [](GLenum name) {
        const GLubyte* text = glGetString(name);
        return text ? std::string(reinterpret_cast<const char*>(text)) : std::string("unknown");
    };
    logInfo("view: OpenGL ", glText(GL_VERSION), " on ", glText(GL_RENDERER));

    bool cullBackFaces = false;
    for (const Material& m : scene.materials) cullBackFaces = cullBackFaces || m.doubleSided;
    // Geometry: the export's mesh (patch corners with their interpolated radiance, and normals).
    const ExportMesh mesh = exportMesh(patches, corners);
    // Textured objects show their light at the corners times the texels (as the headless radiosity
    // view does), the patches' texture coordinates with it.
    const bool textures = scene.hasTextures() && patches.hasUv();
    const CornerValues irradiance = textures ? cornerIrradiance(scene, patches, corners) : CornerValues{};
    // Patches meeting at a corner share one vertex where their values there agree (the corners'
    // interpolation gives them one): the building's 345,232 corners are 217,034 vertices.
    std::vector<float> vertices;
    std::vector<unsigned> vertexOf(mesh.positions.size());
    std::map<std::array<float, SceneDraw::kStride>, unsigned> unique;
    for (size_t i = 0, corner = 0; i < patches.size(); ++i) {
        const bool light = textures && SceneDraw::showsTextures(scene, scene.objects[size_t(patches.object[i])]);
        for (size_t k = 0; k < patches.cornerCount[i]; ++k, ++corner) {
            std::array<float, SceneDraw::kStride> v{};
            const Rgb shown = light ? Rgb(irradiance[i][k] * kInvPi) : mesh.radiance[corner];
            for (int c = 0; c < 3; ++c) {
                v[size_t(c)] = float(mesh.positions[corner][c]);
                v[size_t(3 + c)] = float(shown[c]);
                v[size_t(6 + c)] = float(mesh.normals[corner][c]);
            }
            if (textures) v[9] = float(patches.uv[i][k].x()), v[10] = float(patches.uv[i][k].y());
            const auto [at, added] = unique.emplace(v, unsigned(unique.size()));
            if (added) vertices.insert(vertices.end(), v.begin(), v.end());
            vertexOf[corner] = at->second;
        }
    }
    std::vector<unsigned> triangles, edges;
    for (const auto& t : mesh.triangles)
        for (int v : t) triangles.push_back(vertexOf[size_t(v)]);
    std::vector<int> triangleObject;  // exportMesh's triangles run patch by patch
    for (size_t i = 0, base = 0; i < patches.size(); base += patches.cornerCount[i], ++i) {
        triangleObject.insert(triangleObject.end(), size_t(patches.cornerCount[i] - 2), patches.object[i]);
        for (unsigned k = 0; k < patches.cornerCount[i]; ++k) {
            edges.push_back(vertexOf[base + k]);
            edges.push_back(vertexOf[base + (k + 1) % patches.cornerCount[i]]);
        }
    }
    const double sceneSize = patches.size() ? std::max(patchBounds(patches).diagonal().norm(), 1e-6) : 1.0;
    logDebug("view: ", mesh.positions.size(), " patch corners, ", vertices.size() / SceneDraw::kStride, " vertices");
    // Optional only to be released while its context lives (before glfwDestroyWindow).
    std::optional<SceneDraw> drawn(std::in_place, scene, vertices, triangles, triangleObject, edges, textures,
                                   sceneSize, cullBackFaces);
    SceneDraw& draw = *drawn;
    // Its buffer costs about 0.5 ms a frame at 1280 x 720, more than it saves in a small scene (the
    // textured Cornell box: 60 frames/s with it, 66 without; the building: 27-29 with, 15.6 without).
    const bool culling =
        options.occlusionCulling == "on" || (options.occlusionCulling == "auto" && triangles.size() / 3 > 20000);
    draw.setOcclusionCulling(culling);
    const double probesStart = glfwGetTime();
    draw.renderProbes();
    if (draw.probes())
        logInfo("view: ", draw.probes(), " mirror/glass probes (cube maps of the solved scene) in ",
                glfwGetTime() - probesStart, " s");
    GLuint display = 0;
    glGenVertexArrays(1, &display);
    const GLuint displayProgram = gl::program(kDisplayVertex, kDisplayFragment);

    // The float target the scene is drawn into (linear radiance), resized with the window.
    GLuint fbo = 0, colour = 0, depth = 0;
    int targetWidth = 0, targetHeight = 0;
    auto resizeTarget = [&](int w, int h) {
        if (w == targetWidth && h == targetHeight) return;
        if (fbo) {
            glDeleteFramebuffers(1, &fbo);
            glDeleteTextures(1, &colour);
            glDeleteRenderbuffers(1, &depth);
        }
        glGenFramebuffers(1, &fbo);
        glBindFramebuffer(GL_FRAMEBUFFER, fbo);
        glGenTextures(1, &colour);
        glBindTexture(GL_TEXTURE_2D, colour);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, w, h, 0, GL_RGBA, GL_FLOAT, nullptr);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, colour, 0);
        glGenRenderbuffers(1, &depth);
        glBindRenderbuffer(GL_RENDERBUFFER, depth);
        glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, w, h);
        glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
        if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
            throw Error("view: the OpenGL driver has no float render target");
        targetWidth = w, targetHeight = h;
    };

    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;
    ImGui_ImplGlfw_InitForOpenGL(window, true);
    ImGui_ImplOpenGL3_Init("#version 330");

    Navigation nav;
    Progressive progressive(scene, patches, corners, means, indirect);
    Camera progressiveView;
    GLuint gatherTexture = 0;
    glGenTextures(1, &gatherTexture);
    int shownPasses = 0;
    nav.camera = nav.start = start;
    float stops = float(options.exposureStops);
    int toneMap = 0;  // 0: clamp, as the previews; 1: Reinhard
    const double autoScale = exportExposure(mesh, 0);
    double lastTime = glfwGetTime();
    Keys keys;
    if (!screenshot)
        logInfo(
            "view: left drag orbits, right drag pans, wheel zooms, F toggles fly mode (WASD + mouse), E edges, "
            "R resets, P prints the camera, +/- exposure, T tone mapping, G renders the final gather of the view, Esc "
            "quits");

    double firstFrameEnd = 0;
    for (int frame = 0; !glfwWindowShouldClose(window); ++frame) {
        glfwPollEvents();
        const double now = glfwGetTime();
        ImGui_ImplOpenGL3_NewFrame();
        ImGui_ImplGlfw_NewFrame();
        ImGui::NewFrame();
        const ImGuiIO& io = ImGui::GetIO();
        bool startGather = screenshot && options.gatherPasses > 0 && !progressive.running();
        if (!screenshot || options.wholeWindow) {
            double x = 0, y = 0;
            glfwGetCursorPos(window, &x, &y);
            const bool left = glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
            const bool right = glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS ||
                               glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
            nav.dragging = (left || right) && !io.WantCaptureMouse;
            nav.mouse(x, y, left ? GLFW_MOUSE_BUTTON_LEFT : GLFW_MOUSE_BUTTON_RIGHT, sceneSize);
            if (!io.WantCaptureMouse && io.MouseWheel != 0) nav.zoom(io.MouseWheel);
            if (!io.WantCaptureKeyboard) {
                nav.move(window, now - lastTime, sceneSize);
                if (keys.pressed(window, GLFW_KEY_F)) nav.fly = !nav.fly;
                if (keys.pressed(window, GLFW_KEY_E)) nav.edges = !nav.edges;
                if (keys.pressed(window, GLFW_KEY_R)) nav.camera = nav.start;
                if (keys.pressed(window, GLFW_KEY_P))
                    std::printf("%s\n", cameraJson(nav.camera, scene.sceneUnit()).c_str());
                if (keys.pressed(window, GLFW_KEY_EQUAL) || keys.pressed(window, GLFW_KEY_KP_ADD)) stops += 0.5f;
                if (keys.pressed(window, GLFW_KEY_MINUS) || keys.pressed(window, GLFW_KEY_KP_SUBTRACT)) stops -= 0.5f;
                if (keys.pressed(window, GLFW_KEY_ESCAPE)) glfwSetWindowShouldClose(window, GLFW_TRUE);
                if (keys.pressed(window, GLFW_KEY_G)) startGather = true;
                if (keys.pressed(window, GLFW_KEY_T)) toneMap = 1 - toneMap;
            }
            ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
            ImGui::Begin("penumbra", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
            ImGui::TextUnformatted(options.statistics.c_str());
            ImGui::Text("%zu patches, %zu triangles, %zu vertices", patches.size(), mesh.triangles.size(),
                        vertices.size() / SceneDraw::kStride);
            ImGui::Text("%.1f frames/s", double(io.Framerate));
            ImGui::SliderFloat("exposure (stops)", &stops, -10.0f, 10.0f);
            ImGui::Combo("tone mapping (T)", &toneMap, "clamp (as the previews)\0Reinhard\0");
            ImGui::Checkbox("patch edges (E)", &nav.edges);
            ImGui::Checkbox("fly mode (F, WASD)", &nav.fly);
            if (ImGui::Button("reset view (R)")) nav.camera = nav.start;
            ImGui::SameLine();
            if (ImGui::Button("print camera (P)"))
                std::printf("%s\n", cameraJson(nav.camera, scene.sceneUnit()).c_str());
            if (ImGui::Button("final gather (G)")) startGather = true;
            if (progressive.running()) ImGui::Text("final gather: %d passes (move to go back)", progressive.passes());
            ImGui::End();
        }
        lastTime = now;

        int width = 0, height = 0;
        glfwGetFramebufferSize(window, &width, &height);
        if (width <= 0 || height <= 0) {
            ImGui::EndFrame();
            continue;
        }
        resizeTarget(width, height);
        Camera view = nav.camera;
        view.width = width, view.height = height;
        const Eigen::Matrix4f vp = gl::viewProjection(view, width, height, sceneSize);
        // The progressive final gather: started on G, dropped as soon as the camera moves.
        if (startGather) {
            progressive.start(view);
            progressiveView = view;
            shownPasses = 0;
        } else if (progressive.running() && !sameView(view, progressiveView)) {
            progressive.stop();
        }
        const bool showGather = progressive.running() && progressive.passes() > 0;
        if (showGather && progressive.passes() != shownPasses) {
            const Image mean = progressive.mean();
            shownPasses = progressive.passes();
            glBindTexture(GL_TEXTURE_2D, gatherTexture);
            glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
            glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
            // Image rows run from the top; texture rows from the bottom.
            std::vector<float> rows(mean.rgb.size());
            const size_t stride = size_t(mean.width) * 3;
            for (int y = 0; y < mean.height; ++y)
                std::copy_n(&mean.rgb[size_t(y) * stride], stride, &rows[size_t(mean.height - 1 - y) * stride]);
            glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB32F, mean.width, mean.height, 0, GL_RGB, GL_FLOAT, rows.data());
        }
        if (screenshot && options.gatherPasses > 0 && !options.wholeWindow) {
            if (progressive.passes() < options.gatherPasses) {
                ImGui::EndFrame();
                glfwWaitEventsTimeout(0.01);
                --frame;
                continue;
            }
            progressive.stop();
            saveScreenshot(progressive.mean(), options);
            logInfo("view: wrote ", options.screenshot, " (", width, "x", height, ", final gather, ",
                    progressive.passes(), " passes)");
            ImGui::EndFrame();
            break;
        }

        glBindFramebuffer(GL_FRAMEBUFFER, fbo);
        glViewport(0, 0, width, height);
        glClearColor(0, 0, 0, 1);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        glEnable(GL_DEPTH_TEST);
        draw.draw(vp, view.position);
        if (nav.edges) draw.drawEdges(vp);

        if (screenshot && !options.wholeWindow && frame + 1 >= options.frames) {
            glFinish();
            if (frame >= 2) {  // the frames after the first (which builds what is drawn), as the panel counts them
                const double seconds = glfwGetTime() - firstFrameEnd;
                // A new view's own cost (without the tone mapping, the panel and the swap): the scene
                // drawn ten times more, each finished.
                const double drawStart = glfwGetTime();
                for (int again = 0; again < 10; ++again) {
                    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
                    draw.draw(vp, view.position);
                    if (nav.edges) draw.drawEdges(vp);
                    glFinish();
                }
                const auto [inView, cellsDrawn] = draw.cellsInViewAndDrawn();
                logInfo("view: ", frame, " frames at ", width, "x", height, " in ", seconds, " s: ", frame / seconds,
                        " frames/s; the scene alone drawn in ", 1e3 * (glfwGetTime() - drawStart) / 10, " ms (",
                        cellsDrawn, " of the ", inView, " cells in view drawn, ",
                        culling ? "the others hidden" : "occlusion culling off", ")");
            }
            std::vector<float> pixels(size_t(width) * size_t(height) * 4);
            glReadPixels(0, 0, width, height, GL_RGBA, GL_FLOAT, pixels.data());
            Image image(width, height);
            for (int y = 0; y < height; ++y)
                for (int x = 0; x < width; ++x) {
                    const float* p = &pixels[4 * (size_t(height - 1 - y) * size_t(width) + size_t(x))];
                    image.set(x, y, Rgb(p[0], p[1], p[2]));
                }
            saveScreenshot(image, options);
            logInfo("view: wrote ", options.screenshot, " (", width, "x", height, ", frame ", frame + 1, ")");
            ImGui::EndFrame();
            break;
        }

        glBindFramebuffer(GL_FRAMEBUFFER, 0);
        glViewport(0, 0, width, height);
        glDisable(GL_DEPTH_TEST);
        glUseProgram(displayProgram);
        glActiveTexture(GL_TEXTURE0);
        glBindTexture(GL_TEXTURE_2D, showGather ? gatherTexture : colour);
        glUniform1i(glGetUniformLocation(displayProgram, "image"), 0);
        glUniform1f(glGetUniformLocation(displayProgram, "scale"), float(autoScale * std::pow(2.0, double(stops))));
        glUniform1i(glGetUniformLocation(displayProgram, "reinhard"), toneMap);
        glBindVertexArray(display);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        ImGui::Render();
        ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
        if (screenshot && options.wholeWindow && frame + 1 >= options.frames &&
            progressive.passes() >= options.gatherPasses) {
            std::vector<unsigned char> pixels(size_t(width) * size_t(height) * 3), rows(pixels.size());
            glPixelStorei(GL_PACK_ALIGNMENT, 1);
            glReadBuffer(GL_BACK);
            glReadPixels(0, 0, width, height, GL_RGB, GL_UNSIGNED_BYTE, pixels.data());
            const size_t stride = size_t(width) * 3;
            for (int y = 0; y < height; ++y)
                std::copy_n(&pixels[size_t(height - 1 - y) * stride], stride, &rows[size_t(y) * stride]);
            writeRgb8(options.screenshot, width, height, rows);
            logInfo("view: wrote the window to ", options.screenshot, " (", width, "x", height, ")");
            break;
        }
        glfwSwapBuffers(window);
        if (frame == 0) {
            glFinish();
            firstFrameEnd = glfwGetTime();
        }
    }
    progressive.stop();
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
    drawn.reset();
    glfwDestroyWindow(window);
}

}  // namespace penumbra
