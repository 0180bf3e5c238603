// The parts of bindings/cpp/parallax.hpp the example leaves out, on an in-memory scene without
// artefacts (no GPU): host lighting, photo and composite into parallax::Image and into the
// host's buffer, errors as exceptions, and (with PLX_FEATURE_UNITY) the Unity render events.
// Exit 0 = pass; run by tests/cpp.rs (under valgrind in .ci/run).
#include <cstdio>
#include <cstring>
#include <limits>
#include <vector>

#include "parallax.hpp"

static int failures = 0;
#define EXPECT(cond)                                                            \
    do {                                                                        \
        if (!(cond)) {                                                          \
            std::fprintf(stderr, "%s:%d: EXPECT failed: %s\n", __FILE__, __LINE__, #cond); \
            failures++;                                                         \
        }                                                                       \
    } while (0)

template <class F>
static plx_status status_of(F f) {
    try {
        f();
    } catch (const parallax::Error& e) {
        return e.status();
    }
    return PLX_STATUS_OK;
}

int main() {
    parallax::Context context;
    parallax::Scene scene(context);
    EXPECT(status_of([&] { scene.photo_size(); }) == PLX_STATUS_NOT_AVAILABLE);
    EXPECT(parallax::status_str(PLX_STATUS_NOT_AVAILABLE).find("not available") == 0);

    // Host lighting, read back.
    plx_light sun{PLX_LIGHT_KIND_DIRECTIONAL, {0, 0, 0}, {0, -1, 0}, 0.5f, {2, 3, 4}, 1};
    scene.set_lights({sun});
    const std::vector<plx_light> lights = scene.lights();
    EXPECT(lights.size() == 1 && lights[0].intensity[2] == 4);
    const parallax::MainLight main = scene.main_light();
    EXPECT(main.direction[1] > 0.99f && main.rgb[1] == 3);
    scene.set_lights({});
    EXPECT(scene.lights().empty());
    scene.reset_lights();
    parallax::Sh9 sh9{};
    sh9[0] = sh9[1] = sh9[2] = 0.25f;
    scene.set_sh9(sh9);
    EXPECT(scene.sh9()[1] == 0.25f);
    scene.reset_sh9();
    sh9[4] = std::numeric_limits<float>::infinity();
    EXPECT(status_of([&] { scene.set_sh9(sh9); }) == PLX_STATUS_INVALID_ARGUMENT);
    scene.set_insertion_point({0.1f, -0.5f, -2.0f});
    EXPECT(status_of([&] {
               scene.set_insertion_point({0.0f, std::numeric_limits<float>::quiet_NaN(), -2.0f});
           }) == PLX_STATUS_INVALID_ARGUMENT);
    scene.reset_insertion_point();
    parallax::Image env = parallax::Image::allocate(8, 4, PLX_PIXEL_FORMAT_RGB8);
    std::memset(env.pixels.data(), 128, env.pixels.size());
    scene.set_environment_equirect(env.view());
    // The cube of a constant map is that constant on every face.
    const parallax::Image face = scene.environment_cube_face(2, PLX_PIXEL_FORMAT_RGBA8);
    EXPECT(face.width == scene.environment_cube_size() && face.height == face.width);
    EXPECT(face.at(0, 0)[0] >= 126 && face.at(0, 0)[0] <= 130 && face.at(0, 0)[3] == 255);
    EXPECT(scene.environment_cube_face(5).format == PLX_PIXEL_FORMAT_RGBA_F16);
    EXPECT(status_of([&] { scene.environment_cube_face(6); }) == PLX_STATUS_INVALID_ARGUMENT);
    scene.reset_environment();
    parallax::Image square = parallax::Image::allocate(4, 4, PLX_PIXEL_FORMAT_RGB8);
    EXPECT(status_of([&] { scene.set_environment_equirect(square.view()); }) ==
           PLX_STATUS_INVALID_ARGUMENT);

    // A photo: the composite without artefacts is the photo, in any format.
    const uint32_t w = 8, h = 4;
    parallax::Image left = parallax::Image::allocate(w, h, PLX_PIXEL_FORMAT_RGB8);
    for (size_t i = 0; i < left.pixels.size(); i++) left.pixels[i] = static_cast<uint8_t>(i * 7);
    scene.set_photo(left.view());
    EXPECT(scene.photo_size() == std::make_pair(w, h));
    const parallax::Image photo = scene.photo(PLX_PIXEL_FORMAT_RGB8);
    EXPECT(photo.pixels == left.pixels);
    parallax::Image mask;
    const parallax::Image bgra = scene.render(PLX_PIXEL_FORMAT_BGRA8, &mask);
    EXPECT(bgra.stride == w * 4 && mask.format == PLX_PIXEL_FORMAT_GRAY8);
    EXPECT(bgra.at(1, 2)[0] == left.at(1, 2)[2] && bgra.at(1, 2)[3] == 255);
    EXPECT(mask.pixels == std::vector<uint8_t>(w * h, 0));
    plx_render_options options = parallax::Scene::default_render_options();
    std::vector<float> linear(w * h * 4, -1.0f);
    scene.render(plx_image_out{reinterpret_cast<uint8_t*>(linear.data()), w, h, w * 16,
                               PLX_PIXEL_FORMAT_RGBA_F32},
                 nullptr, &options);
    EXPECT(linear[3] == 1.0f && linear[0] >= 0.0f);
    parallax::Image wrong = parallax::Image::allocate(w + 1, h, PLX_PIXEL_FORMAT_RGBA8);
    EXPECT(status_of([&] { scene.render(wrong.out()); }) == PLX_STATUS_SIZE_MISMATCH);
    options.shadow_map_size = 1;
    EXPECT(status_of([&] { scene.render(PLX_PIXEL_FORMAT_RGBA8, nullptr, &options); }) ==
           PLX_STATUS_INVALID_ARGUMENT);

#if defined(PLX_FEATURE_UNITY)
    // What Unity's render thread would run, called here directly.
    parallax::Image target = parallax::Image::allocate(w, h, PLX_PIXEL_FORMAT_RGBA8);
    EXPECT(parallax::unity::interfaces() == nullptr);
    UnityPluginLoad(nullptr);
    parallax::unity::set_render_target(3, scene, target.out());
    uint64_t runs = 0;
    EXPECT(parallax::unity::last_event_status(3, &runs) == PLX_STATUS_NOT_AVAILABLE && runs == 0);
    GetRenderEventFunc()(3);
    EXPECT(parallax::unity::last_event_status(3, &runs) == PLX_STATUS_OK && runs == 1);
    EXPECT(target.at(1, 2)[0] == left.at(1, 2)[0]);
    parallax::unity::clear_render_target(3);
    GetRenderEventFunc()(3);
    EXPECT(parallax::unity::last_event_status(3) == PLX_STATUS_INVALID_ARGUMENT);
    EXPECT(parallax::unity::last_event_message(3).find("event id 3") != std::string::npos);
    UnityPluginUnload();
#endif

    if (failures) std::fprintf(stderr, "%d expectation(s) failed\n", failures);
    return failures ? 1 : 0;
}
