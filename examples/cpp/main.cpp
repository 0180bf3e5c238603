// A C++ host of Parallax: loads a stereo pair, reconstructs depth, mesh and support surfaces,
// inserts a glTF model standing on the scene at a chosen pixel and, given OUT.ppm, renders the
// composite and saves it as a binary PPM (and the model's coverage as a PGM next to it), printing
// what it found as key=value lines (read by tests/cpp.rs and tests/packaging.rs).
//
//   parallax_example_cpp LEFT.png RIGHT.png MODEL.glb FOCAL_PX BASELINE_M X Y [OUT.ppm]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "parallax.hpp"

// Writes an RGB8 image as binary PPM ("P6") or a GRAY8 one as PGM ("P5").
static bool save_pnm(const std::string& path, const parallax::Image& image, const char* magic) {
    std::ofstream file(path, std::ios::binary);
    file << magic << "\n" << image.width << " " << image.height << "\n255\n";
    const size_t row = image.width * parallax::Image::bytes_per_pixel(image.format);
    for (uint32_t y = 0; y < image.height; y++)
        file.write(reinterpret_cast<const char*>(image.at(0, y)), static_cast<std::streamsize>(row));
    return static_cast<bool>(file);
}

int main(int argc, char** argv) {
    if (argc != 8 && argc != 9) {
        std::fprintf(stderr, "usage: %s LEFT RIGHT MODEL.glb FOCAL_PX BASELINE_M X Y [OUT.ppm]\n",
                     argv[0]);
        return 2;
    }
    try {
        parallax::set_log_callback(
            [](parallax::LogLevel level, std::string_view message) {
                if (level <= parallax::LogLevel::Warn)
                    std::fprintf(stderr, "parallax: %.*s\n", static_cast<int>(message.size()),
                                 message.data());
            },
            parallax::LogLevel::Warn);

        parallax::Context context;
        parallax::Scene scene(context);
        scene.load_stereo_pair(argv[1], argv[2]);

        // Disparity in pixels; its size is the photo's.
        const parallax::FloatGrid disparity = scene.disparity();
        const uint32_t w = disparity.width, h = disparity.height;
        std::printf("disparity_centre_px=%.3f\n", disparity.at(w / 2, h / 2));
        // The photo in a host buffer as a D3D/Unity BGRA8 texture would take it.
        std::vector<uint8_t> bgra(static_cast<size_t>(w) * h * 4);
        scene.photo(plx_image_out{bgra.data(), w, h, w * 4u, PLX_PIXEL_FORMAT_BGRA8});
        double mean = 0;
        for (size_t i = 0; i < bgra.size(); i += 4) mean += bgra[i + 1];
        std::printf("photo_mean_green=%.2f\n", mean / (static_cast<double>(w) * h));

        plx_calibration calibration{};
        calibration.focal_px = std::atof(argv[4]);
        calibration.baseline_m = std::atof(argv[5]);
        calibration.cx = w / 2.0;
        calibration.cy = h / 2.0;
        scene.set_calibration(calibration);

        int stages = 0;
        scene.set_progress_callback([&](std::string_view, float fraction) {
            stages += fraction == 1.0f;
            return true;
        });

        parallax::FloatGrid depth = scene.depth();
        std::printf("size=%ux%u\n", w, h);
        std::printf("depth_centre_m=%.4f\n", depth.at(w / 2, h / 2));

        parallax::Mesh mesh = scene.mesh();
        std::printf("mesh_vertices=%zu\nmesh_triangles=%zu\n", mesh.vertex_count,
                    mesh.triangle_count());

        // Support surfaces found in the mesh (planes; none when the depth is too noisy).
        const parallax::Span<plx_surface> surfaces = scene.surfaces();
        std::printf("surfaces=%zu\n", surfaces.size());
        const parallax::Vec3 up = scene.up();
        std::printf("up=%.4f,%.4f,%.4f\n", up[0], up[1], up[2]);

        // What the camera sees at the chosen pixel, and the model standing there, 0.3 m at most.
        const float px = static_cast<float>(std::atof(argv[6]));
        const float py = static_cast<float>(std::atof(argv[7]));
        const plx_hit hit = scene.pick(px, py);
        std::printf("hit=%u\npoint=%.4f,%.4f,%.4f\n", hit.hit, hit.point[0], hit.point[1],
                    hit.point[2]);
        const parallax::Scene::ArtefactId id = scene.add_artefact(argv[3]);
        const parallax::Matrix4 m = scene.place_artefact(id, px, py, 0.3f, 30.0f);
        // The room's light is estimated around the object: it is lit from where it stands.
        scene.set_insertion_point({m[12], m[13], m[14]});
        const parallax::Bounds b = scene.artefact_bounds(id);
        // The model's base centre and top centre in the world (column-major model → world).
        auto world = [&](float x, float y, float z) {
            parallax::Vec3 p{};
            for (int r = 0; r < 3; r++) p[r] = m[r] * x + m[4 + r] * y + m[8 + r] * z + m[12 + r];
            return p;
        };
        const float cx = (b.local_min[0] + b.local_max[0]) / 2;
        const float cz = (b.local_min[2] + b.local_max[2]) / 2;
        const parallax::Vec3 base = world(cx, b.local_min[1], cz);
        const parallax::Vec3 top = world(cx, b.local_max[1], cz);
        std::printf("artefact_base=%.4f,%.4f,%.4f\n", base[0], base[1], base[2]);
        std::printf("artefact_top=%.4f,%.4f,%.4f\n", top[0], top[1], top[2]);
        std::printf("artefact_warnings=%zu\n", scene.artefact_warnings(id).size());

        // Several compositions of one reconstruction: the clone reuses depth and mesh.
        parallax::Scene variant = scene.clone();
        variant.remove_artefact(id);
        variant.mesh();
        std::printf("clone_reused_mesh=%d\n",
                    variant.report().find("\"status\": \"reused\"") != std::string::npos);
        std::printf("progress_stages=%d\n", stages);

        if (argc == 9) {
            // The lighting the model is rendered with: the estimated lights and ambient SH9.
            const std::vector<plx_light> lights = scene.lights();
            const parallax::Sh9 sh9 = scene.sh9();
            std::printf("lights=%zu\nsh9_dc=%.4f,%.4f,%.4f\n", lights.size(), sh9[0], sh9[1],
                        sh9[2]);

            // The composite: the photo with the model rendered in, and the model's coverage.
            plx_render_options options = parallax::Scene::default_render_options();
            options.shadow_map_size = 512;
            parallax::Image mask;
            const parallax::Image composite =
                scene.render(PLX_PIXEL_FORMAT_RGB8, &mask, &options);
            size_t covered = 0;
            for (uint32_t y = 0; y < mask.height; y++)
                for (uint32_t x = 0; x < mask.width; x++) covered += *mask.at(x, y) > 127;
            std::printf("composite_size=%ux%u\nmask_pixels=%zu\n", composite.width,
                        composite.height, covered);
            std::printf("mask_at_pixel=%u\n",
                        static_cast<unsigned>(
                            *mask.at(static_cast<uint32_t>(px), static_cast<uint32_t>(py))));
            const std::string path = argv[8];
            if (!save_pnm(path, composite, "P6") ||
                !save_pnm(path.substr(0, path.find_last_of('.')) + "-mask.pgm", mask, "P5")) {
                std::fprintf(stderr, "cannot write %s\n", path.c_str());
                return 1;
            }
            std::printf("composite=%s\n", path.c_str());
        }

        parallax::set_log_callback(nullptr);
        return 0;
    } catch (const parallax::Error& e) {
        std::fprintf(stderr, "parallax error %d: %s\n", static_cast<int>(e.status()), e.what());
        return 1;
    }
}
