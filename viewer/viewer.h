// The interactive viewer (`penumbra view`): the solved radiosity as smooth per-vertex radiance on
// the patches, rasterised with OpenGL 3.3 core in a GLFW window, with a Dear ImGui panel. Orbit,
// pan, zoom and fly; exposure; patch edges; reset; the current camera printed as JSON; on G, the
// final-gather render of the current view, refined pass by pass while the camera rests. With
// `screenshot` set it draws `frames` frames from the start camera at its resolution, saves the last
// (tone-mapped like render's PNG previews) and returns.
#pragma once

#include <string>

#include "mesh/patches.h"
#include "mesh/scene.h"

namespace penumbra {

struct ViewerOptions {
    std::string screenshot;  // PNG to save, then exit; empty: interactive
    int frames = 3;          // frames drawn before the screenshot
    double exposureStops = 0;
    std::string statistics;    // text for the panel (the solve's report, summarised)
    int gatherPasses = 0;      // with `screenshot`: save the progressive final gather after this many passes
    bool wholeWindow = false;  // with `screenshot`: the window as shown (panel included), not the picture alone
    // Cells hidden behind the scene's walls are not drawn (render/occlusion.h): "auto" (in scenes of
    // more than 20,000 triangles), "on" or "off".
    std::string occlusionCulling = "auto";
};

// Throws Error, pointing to the headless forms, when there is no display to open a window on.
void requireDisplay();

// `corners`: the displayed radiosity at each patch corner, `means` per patch (the final gather's
// reading, meanPreservingCorners), `indirect` the solve's indirect irradiance per corner (the final
// gather's fast path; may be empty). Throws Error when no window can be opened (no display).
void runViewer(const Scene& scene, const PatchSet& patches, const CornerValues& corners, const std::vector<Rgb>& means,
               const CornerValues& indirect, const Camera& start, const ViewerOptions& options);

}  // namespace penumbra
