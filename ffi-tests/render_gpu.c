/* plx_scene_render on the GPU from C: a wall 3 m away with a post 1.5 m away on its left (host
 * depth, stereo skipped), a grey photo, one host light from behind the camera, and two boxes
 * (built here as GLB bytes): the one in front of the wall is drawn and its shadow darkens the
 * wall beside it; the one behind the post is hidden by it; pixels far from both keep the photo.
 * Under valgrind or the sanitizers (PARALLAX_FFI_NO_GPU, set by tests/ffi.rs) the render is left
 * out: Mesa's software GPU driver reports errors and leaks of its own there. */
#include <math.h>

#include "check.h"
/* after check.h: it uses CHECK */
#include "box_glb.h"

enum { W = 80, H = 60 };
static const float F = 60.0f, CX = 40.0f, CY = 30.0f;

/* A column-major transform that turns the file's box (BOX_MIN..BOX_MAX) into a 0.3 m cube centred
 * on (x, y, z) in the camera frame. */
static void cube_at(float x, float y, float z, float m[16]) {
    const float s = 0.3f;
    const float sx = s / (BOX_MAX[0] - BOX_MIN[0]), sy = s / (BOX_MAX[1] - BOX_MIN[1]),
                sz = s / (BOX_MAX[2] - BOX_MIN[2]);
    memset(m, 0, 16 * sizeof(float));
    m[0] = sx;
    m[5] = sy;
    m[10] = sz;
    m[12] = x - sx * (BOX_MIN[0] + BOX_MAX[0]) / 2.0f;
    m[13] = y - sy * (BOX_MIN[1] + BOX_MAX[1]) / 2.0f;
    m[14] = z - sz * (BOX_MIN[2] + BOX_MAX[2]) / 2.0f;
    m[15] = 1.0f;
}

static int px(float x, float z) { return (int)(CX + F * x / -z); }

int main(void) {
    plx_context *ctx = NULL;
    CHECK_STATUS(NULL, plx_context_new(NULL, &ctx), PLX_STATUS_OK);
    plx_scene *scene = NULL;
    CHECK_STATUS(ctx, plx_scene_new(ctx, &scene), PLX_STATUS_OK);

    static uint8_t photo[W * H * 4];
    memset(photo, 150, sizeof photo);
    plx_image view = {photo, W, H, W * 4, PLX_PIXEL_FORMAT_RGBA8};
    CHECK_STATUS(scene, plx_scene_set_stereo_pair(scene, &view, &view), PLX_STATUS_OK);
    static float depth[W * H];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) depth[y * W + x] = x < 24 ? 1.5f : 3.0f;
    const plx_camera camera = {F, F, CX, CY};
    CHECK_STATUS(scene, plx_scene_set_depth(scene, depth, W, H, W * sizeof(float), NULL, 0, &camera),
                 PLX_STATUS_OK);
    /* Travelling away from the camera, to the right and down: shadows fall right and below. */
    const float d[3] = {0.35f, -0.35f, -1.0f};
    const float n = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    plx_light light = {PLX_LIGHT_KIND_DIRECTIONAL, {0, 0, 0}, {d[0] / n, d[1] / n, d[2] / n}, 0.5f,
                       {1.5f, 1.5f, 1.5f}, 1.0f};
    CHECK_STATUS(scene, plx_scene_set_lights(scene, &light, 1), PLX_STATUS_OK);
    float sh9[27] = {0};
    sh9[0] = sh9[1] = sh9[2] = 0.2f;
    CHECK_STATUS(scene, plx_scene_set_sh9(scene, sh9), PLX_STATUS_OK);

    static uint8_t glb[2048];
    const size_t len = box_glb(glb, NULL);
    float m[16];
    uint32_t front = 0, hidden = 0;
    const float front_x = 0.4f, front_z = -2.5f, hidden_x = -1.0f, hidden_z = -2.2f;
    cube_at(front_x, 0.0f, front_z, m);
    CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, glb, len, m, &front), PLX_STATUS_OK);
    cube_at(hidden_x, 0.0f, hidden_z, m);
    CHECK_STATUS(scene, plx_scene_add_artefact_memory(scene, glb, len, m, &hidden), PLX_STATUS_OK);

    static uint8_t out_px[W * H * 4], mask_px[W * H];
    plx_image_out out = {out_px, W, H, W * 4, PLX_PIXEL_FORMAT_RGBA8};
    plx_image_out mask = {mask_px, W, H, W, PLX_PIXEL_FORMAT_GRAY8};
    plx_render_options opts;
    CHECK_STATUS(NULL, plx_render_options_init(&opts), PLX_STATUS_OK);
    opts.shadows = PLX_SHADOW_MODE_PCSS;
    /* The wrong output size is refused before any GPU work. */
    plx_image_out small = {out_px, W - 1, H, W * 4, PLX_PIXEL_FORMAT_RGBA8};
    CHECK_STATUS(scene, plx_scene_render(scene, &opts, &small, NULL), PLX_STATUS_SIZE_MISMATCH);

    if (getenv("PARALLAX_FFI_NO_GPU")) {
        printf("render_gpu: GPU render left out under valgrind / sanitizers\n");
    } else {
        plx_status s = plx_scene_render(scene, &opts, &out, &mask);
        if (s == PLX_STATUS_GPU) {
            /* No adapter on this machine: a clear error, and the scene still answers. */
            CHECK_MESSAGE(scene, "adapter");
            CHECK_STATUS(scene, plx_scene_photo(scene, &out), PLX_STATUS_OK);
        } else {
            CHECK_STATUS(scene, s, PLX_STATUS_OK);
            /* The front box covers its centre pixel and is not the photo there. */
            const int fx = px(front_x, front_z), fy = (int)CY;
            CHECK(mask_px[fy * W + fx] > 200);
            CHECK(out_px[(fy * W + fx) * 4] != photo[(fy * W + fx) * 4]);
            /* The hidden box covers nothing: the post in front keeps the photo. */
            const int hx = px(hidden_x, hidden_z);
            CHECK(hx > 4 && hx < 20);
            for (int y = 24; y < 36; y++)
                for (int x = hx - 3; x <= hx + 3; x++) {
                    CHECK(mask_px[y * W + x] == 0);
                    CHECK(abs((int)out_px[(y * W + x) * 4] - 150) <= 2);
                }
            /* The shadow: wall pixels right of and below the box, uncovered and darker. */
            int shadowed = 0;
            for (int y = fy; y < H; y++)
                for (int x = fx; x < W; x++)
                    if (mask_px[y * W + x] == 0 && out_px[(y * W + x) * 4] < 150 - 20) shadowed++;
            CHECK(shadowed >= 6);
            printf("render_gpu: rendered, %d shadowed wall pixels\n", shadowed);
            /* Far from both (top right), the photo. */
            CHECK(abs((int)out_px[(2 * W + 76) * 4] - 150) <= 2);
            CHECK(out_px[(fy * W + fx) * 4 + 3] == 255);
        }
    }
    plx_scene_free(scene);
    plx_context_free(ctx);
    TEST_EXIT();
}
