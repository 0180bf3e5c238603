/* Reconstruction through the C API from the host's own depth: a floor 1 m below the camera, a box
 * standing on it and a wall 6 m away, with depth computed analytically here. Checks depth-buffer
 * encodings, the mesh, a pick, a placement, the surfaces, and the error paths. */
#include <math.h>

#include "check.h"

enum { W = 64, H = 48 };
static const float F = 60.0f, CX = W / 2.0f, CY = H / 2.0f;
static const float FLOOR_Y = -1.0f, WALL_Z = -6.0f;
static const float BOX_MIN[3] = {-0.4f, -1.0f, -3.5f}, BOX_MAX[3] = {0.4f, -0.5f, -2.7f};

/* Direction of the ray through continuous pixel (u, v), with z = -1 so that t is depth. */
static void ray_dir(float u, float v, float d[3]) {
    d[0] = (u - CX) / F;
    d[1] = -(v - CY) / F;
    d[2] = -1.0f;
}

/* Depth along the optical axis (metres) seen at continuous pixel (u, v). */
static float depth_at(float u, float v) {
    float d[3];
    ray_dir(u, v, d);
    float t = -WALL_Z;
    if (d[1] < 0.0f && FLOOR_Y / d[1] < t) t = FLOOR_Y / d[1];
    float lo = 0.0f, hi = INFINITY; /* slab test of the box */
    for (int k = 0; k < 3; k++) {
        float a = BOX_MIN[k] / d[k], b = BOX_MAX[k] / d[k];
        if (a > b) { float s = a; a = b; b = s; }
        if (a > lo) lo = a;
        if (b < hi) hi = b;
    }
    if (lo <= hi && lo > 0.0f && lo < t) t = lo;
    return t;
}

static int finite3(const float *p) { return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]); }

static float at(const plx_float_view *v, unsigned x, unsigned y) {
    return *(const float *)((const uint8_t *)v->data + y * v->stride + x * sizeof(float));
}

int main(void) {
    static float depth[W * H], nan_depth[W * H], conf[W * H];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            depth[y * W + x] = depth_at(x + 0.5f, y + 0.5f);
            nan_depth[y * W + x] = NAN;
            conf[y * W + x] = 1.0f;
        }
    depth[0] = NAN; /* one hole */
    plx_camera cam = {F, F, CX, CY};

    plx_context *ctx = NULL;
    plx_scene *scene = NULL;
    CHECK_STATUS(NULL, plx_context_new(NULL, &ctx), PLX_STATUS_OK);
    CHECK_STATUS(ctx, plx_scene_new(ctx, &scene), PLX_STATUS_OK);

    /* Nothing yet. */
    plx_mesh_view mesh = {0};
    CHECK_STATUS(scene, plx_scene_mesh(scene, &mesh), PLX_STATUS_NOT_AVAILABLE);
    CHECK(mesh.positions == NULL);

    /* Bad depth input. */
    CHECK_STATUS(NULL, plx_scene_set_depth(NULL, depth, W, H, W * 4, NULL, 0, &cam),
                 PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_set_depth(scene, NULL, W, H, W * 4, NULL, 0, &cam),
                 PLX_STATUS_NULL_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_set_depth(scene, depth, W, H, W * 4 - 1, NULL, 0, &cam),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "stride");
    CHECK_STATUS(scene, plx_scene_set_depth(scene, depth, 0, H, W * 4, NULL, 0, &cam),
                 PLX_STATUS_INVALID_ARGUMENT);
    conf[5] = 1.5f;
    CHECK_STATUS(scene, plx_scene_set_depth(scene, depth, W, H, W * 4, conf, W * 4, &cam),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "confidence");
    conf[5] = 1.0f;
    plx_camera bad_cam = {-1.0f, F, CX, CY};
    CHECK_STATUS(scene, plx_scene_set_depth(scene, depth, W, H, W * 4, NULL, 0, &bad_cam),
                 PLX_STATUS_INVALID_ARGUMENT);
    {
        /* A host depth of another size than the photo. */
        static uint8_t gray[W * H];
        plx_scene *other = NULL;
        CHECK_STATUS(ctx, plx_scene_new(ctx, &other), PLX_STATUS_OK);
        plx_image img = {gray, W, H, W, PLX_PIXEL_FORMAT_GRAY8};
        CHECK_STATUS(other, plx_scene_set_stereo_pair(other, &img, &img), PLX_STATUS_OK);
        CHECK_STATUS(other, plx_scene_set_depth(other, depth, W - 1, H, W * 4, NULL, 0, NULL),
                     PLX_STATUS_SIZE_MISMATCH);
        plx_scene_free(other);
    }

    CHECK_STATUS(scene, plx_scene_set_depth(scene, depth, W, H, W * 4, conf, W * 4, &cam),
                 PLX_STATUS_OK);

    /* Depth buffers at a floor pixel against the formulas, with an explicit clip range. */
    const unsigned px = 5, py = 40;
    const double z = depth_at(px + 0.5f, py + 0.5f), n = 0.5, f = 20.0;
    plx_float_view buf = {0};
    CHECK_STATUS(scene, plx_scene_depth_buffer(scene, PLX_DEPTH_ENCODING_LINEAR_METERS, 0, 0, &buf),
                 PLX_STATUS_OK);
    CHECK(buf.width == W && buf.height == H);
    CHECK(fabs(at(&buf, px, py) - z) < 1e-5 * z);
    CHECK(isinf(at(&buf, 0, 0))); /* the hole */
    CHECK_STATUS(scene, plx_scene_depth_buffer(scene, PLX_DEPTH_ENCODING_OPENGL_WINDOW, n, f, &buf),
                 PLX_STATUS_OK);
    CHECK(fabs(at(&buf, px, py) - ((f + n) / (2 * (f - n)) - f * n / ((f - n) * z) + 0.5)) < 1e-6);
    CHECK(at(&buf, 0, 0) == 1.0f);
    CHECK_STATUS(scene,
                 plx_scene_depth_buffer(scene, PLX_DEPTH_ENCODING_WEBGPU_ZERO_TO_ONE, n, f, &buf),
                 PLX_STATUS_OK);
    CHECK(fabs(at(&buf, px, py) - f * (z - n) / ((f - n) * z)) < 1e-6);
    /* Automatic clip range: the camera reports it, reversed-Z uses it. */
    plx_camera got;
    float near = 0, far = 0;
    CHECK_STATUS(scene, plx_scene_camera(scene, &got, &near, &far), PLX_STATUS_OK);
    CHECK(got.fx == F && got.cy == CY);
    CHECK(near > 0 && near < z && far > 6.0f);
    CHECK_STATUS(scene, plx_scene_depth_buffer(scene, PLX_DEPTH_ENCODING_REVERSED_Z, 0, 0, &buf),
                 PLX_STATUS_OK);
    CHECK(fabs(at(&buf, px, py) - near * (far - z) / ((far - near) * z)) < 1e-6);
    CHECK(at(&buf, 0, 0) == 0.0f);
    CHECK_STATUS(scene, plx_scene_depth_buffer(scene, 7, 0, 0, &buf), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_depth_buffer(scene, 0, 5, 5, &buf), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_depth_buffer(scene, 0, 0, 0, NULL), PLX_STATUS_NULL_ARGUMENT);

    /* Clip planes: near >= far or near <= 0 are errors; a valid range is used. */
    CHECK_STATUS(scene, plx_scene_set_clip(scene, 2.0f, 1.0f), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "far");
    CHECK_STATUS(scene, plx_scene_set_clip(scene, -1.0f, 1.0f), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_set_clip(scene, 0.0f, 1.0f), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_set_clip(scene, 0.25f, 50.0f), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_camera(scene, &got, &near, &far), PLX_STATUS_OK);
    CHECK(near == 0.25f && far == 50.0f);
    CHECK_STATUS(scene, plx_scene_set_clip(scene, 0.0f, 0.0f), PLX_STATUS_OK);

    /* The mesh: non-empty, indices in range, no NaN. */
    CHECK_STATUS(scene, plx_scene_mesh(scene, &mesh), PLX_STATUS_OK);
    CHECK(mesh.vertex_count > 0 && mesh.index_count > 0 && mesh.index_count % 3 == 0);
    for (size_t i = 0; i < mesh.index_count; i++) CHECK(mesh.indices[i] < mesh.vertex_count);
    int bad = 0;
    for (size_t v = 0; v < mesh.vertex_count; v++) {
        const float *nrm = mesh.normals + 3 * v;
        bad += !finite3(mesh.positions + 3 * v) || !finite3(nrm) || !finite3(mesh.tangents + 4 * v) ||
               !isfinite(mesh.uvs[2 * v]) || !isfinite(mesh.uvs[2 * v + 1]) ||
               fabsf(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2] - 1.0f) > 1e-3f;
    }
    CHECK(bad == 0);

    /* The report of that call: stereo skipped because the host gave depth. */
    char report[8192];
    CHECK_STATUS(scene, plx_scene_report(scene, report, sizeof report, NULL), PLX_STATUS_OK);
    CHECK(strstr(report, "\"name\": \"stereo\",\n      \"status\": \"skipped\"") != NULL);
    CHECK(strstr(report, "host depth given") != NULL);

    /* Picks against the analytic points: the floor, and the box's front face, between the mesh's
     * vertices and exactly on them (pixel centres) and on a shared edge, where a ray must not fall
     * between two triangles. */
    const float picks[4][2] = {{px + 0.3f, py + 0.7f}, {32.3f, 40.7f}, {px + 0.5f, py + 0.5f}, {px + 1.0f, py + 0.5f}};
    for (int k = 0; k < 4; k++) {
        float u = picks[k][0], v = picks[k][1], d[3];
        ray_dir(u, v, d);
        float t = depth_at(u, v);
        plx_hit hit;
        CHECK_STATUS(scene, plx_scene_pick(scene, u, v, &hit), PLX_STATUS_OK);
        CHECK(hit.hit == 1);
        float err = 0;
        for (int c = 0; c < 3; c++) err += fabsf(hit.point[c] - d[c] * t);
        CHECK(err < 2e-3f * t);
        CHECK(fabsf(hit.distance - t * sqrtf(d[0] * d[0] + d[1] * d[1] + 1)) < 2e-3f * t);
    }
    plx_hit miss;
    CHECK_STATUS(scene, plx_scene_pick(scene, -100.0f, 10.0f, &miss), PLX_STATUS_OK);
    CHECK(miss.hit == 0);
    CHECK_STATUS(scene, plx_scene_pick(scene, NAN, 10.0f, &miss), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_pick(scene, 1.0f, 1.0f, NULL), PLX_STATUS_NULL_ARGUMENT);

    /* Surfaces include the floor, horizontal; up is +Y. */
    size_t count = 0;
    const plx_surface *surfaces = NULL;
    CHECK_STATUS(scene, plx_scene_surfaces(scene, &count, &surfaces), PLX_STATUS_OK);
    CHECK(count > 0 && surfaces != NULL);
    int floor_found = 0;
    for (size_t i = 0; i < count; i++)
        floor_found |= surfaces[i].kind == PLX_SURFACE_KIND_HORIZONTAL &&
                       surfaces[i].normal[1] > 0.99f && fabsf(surfaces[i].offset - FLOOR_Y) < 0.02f &&
                       surfaces[i].inliers > 0 && surfaces[i].area_m2 > 0;
    CHECK(floor_found);
    float up[3];
    CHECK_STATUS(scene, plx_scene_up(scene, up), PLX_STATUS_OK);
    CHECK(up[1] > 0.99f);
    CHECK_STATUS(scene, plx_scene_surfaces(scene, NULL, &surfaces), PLX_STATUS_NULL_ARGUMENT);

    /* The host's gravity (any length) wins over the planes' and reclassifies them; NULL goes
     * back; a zero vector is refused. */
    const float imu_up[3] = {0.0f, 2.0f, 2.0f}; /* pitched 45°: the floor is not horizontal */
    CHECK_STATUS(scene, plx_scene_set_up(scene, imu_up), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_up(scene, up), PLX_STATUS_OK);
    CHECK(fabsf(up[0]) < 1e-6f && fabsf(up[1] - 0.70710678f) < 1e-5f && fabsf(up[2] - 0.70710678f) < 1e-5f);
    CHECK_STATUS(scene, plx_scene_surfaces(scene, &count, &surfaces), PLX_STATUS_OK);
    for (size_t i = 0; i < count; i++) CHECK(surfaces[i].kind != PLX_SURFACE_KIND_HORIZONTAL);
    const float zero[3] = {0.0f, 0.0f, 0.0f};
    CHECK_STATUS(scene, plx_scene_set_up(scene, zero), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "up must be");
    CHECK_STATUS(scene, plx_scene_set_up(scene, NULL), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_up(scene, up), PLX_STATUS_OK);
    CHECK(up[1] > 0.99f);
    CHECK_STATUS(scene, plx_scene_surfaces(scene, &count, &surfaces), PLX_STATUS_OK);

    /* Placement on the floor: base (translation, column-major 12..14) on the floor, +Y up, scaled. */
    float m[16];
    CHECK_STATUS(scene, plx_scene_place(scene, px + 0.3f, py + 0.7f, 0.2f, 30.0f, m), PLX_STATUS_OK);
    CHECK(fabsf(m[13] - FLOOR_Y) < 0.01f);
    CHECK(fabsf(m[4]) < 1e-3f && fabsf(m[5] - 0.2f) < 2e-3f && fabsf(m[6]) < 1e-3f);
    CHECK(fabsf(m[3]) < 1e-6f && fabsf(m[15] - 1.0f) < 1e-6f);
    /* Straight down onto a visible part of the floor, left of the box. */
    const float origin[3] = {-1.493f, 0.0f, -4.017f}, down[3] = {0.0f, -1.0f, 0.0f};
    CHECK_STATUS(scene, plx_scene_place_on_ray(scene, origin, down, 0.5f, 0.0f, m), PLX_STATUS_OK);
    CHECK(fabsf(m[13] - FLOOR_Y) < 0.01f && fabsf(m[14] + 4.017f) < 1e-3f);
    CHECK_STATUS(scene, plx_scene_place(scene, -100.0f, 10.0f, 0.2f, 0.0f, m),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_place(scene, 5.5f, 40.5f, -1.0f, 0.0f, m),
                 PLX_STATUS_INVALID_ARGUMENT);
    CHECK_STATUS(scene, plx_scene_place(scene, 5.5f, 40.5f, 1.0f, 0.0f, NULL),
                 PLX_STATUS_NULL_ARGUMENT);

    /* Mesh options: a triangle budget; bad values are rejected. */
    plx_mesh_options mo;
    CHECK_STATUS(NULL, plx_mesh_options_init(&mo), PLX_STATUS_OK);
    mo.max_triangles = 100;
    CHECK_STATUS(scene, plx_scene_set_mesh_options(scene, &mo), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_mesh(scene, &mesh), PLX_STATUS_OK);
    CHECK(mesh.index_count / 3 <= 100 && mesh.index_count > 0);
    for (size_t i = 0; i < mesh.index_count; i++) CHECK(mesh.indices[i] < mesh.vertex_count);
    /* Normals: on a detected surface the plane's (default), else each vertex's own fit. A depth
     * ripple of 0.3 % scatters the own fits on the floor. */
    CHECK_STATUS(NULL, plx_mesh_options_init(&mo), PLX_STATUS_OK);
    CHECK(mo.snap_to_surfaces == 1);
    static float rippled[W * H];
    for (int i = 0; i < W * H; i++) rippled[i] = depth[i] * (1.0f + 0.003f * sinf(7.0f * i));
    CHECK_STATUS(scene, plx_scene_set_depth(scene, rippled, W, H, W * 4, NULL, 0, &cam),
                 PLX_STATUS_OK);
    for (int snap = 1; snap >= 0; snap--) {
        mo.snap_to_surfaces = (uint32_t)snap;
        CHECK_STATUS(scene, plx_scene_set_mesh_options(scene, &mo), PLX_STATUS_OK);
        CHECK_STATUS(scene, plx_scene_mesh(scene, &mesh), PLX_STATUS_OK);
        /* Floor vertices in the bottom-left corner, clear of the box: how many share one normal. */
        size_t floor = 0, most_alike = 0;
        for (size_t v = 0; v < mesh.vertex_count; v++) {
            if (mesh.uvs[2 * v] > 0.3f || mesh.uvs[2 * v + 1] < 0.85f) continue;
            floor++;
            const float *a = mesh.normals + 3 * v;
            size_t alike = 0;
            for (size_t u = 0; u < mesh.vertex_count; u++) {
                if (mesh.uvs[2 * u] > 0.3f || mesh.uvs[2 * u + 1] < 0.85f) continue;
                const float *b = mesh.normals + 3 * u;
                alike += a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
            }
            if (alike > most_alike) most_alike = alike;
        }
        CHECK(floor > 50);
        if (snap) CHECK(most_alike * 10 >= floor * 9); /* the floor plane's normal */
        else CHECK(most_alike * 2 < floor);            /* each its own */
    }
    CHECK_STATUS(scene, plx_scene_set_depth(scene, depth, W, H, W * 4, NULL, 0, &cam), PLX_STATUS_OK);
    mo.step = 0;
    CHECK_STATUS(scene, plx_scene_set_mesh_options(scene, &mo), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "step");
    CHECK_STATUS(scene, plx_scene_set_mesh_options(scene, NULL), PLX_STATUS_OK);
    CHECK_STATUS(NULL, plx_mesh_options_init(NULL), PLX_STATUS_NULL_ARGUMENT);

    /* All depth invalid: a clear error for the mesh, no surfaces. */
    CHECK_STATUS(scene, plx_scene_set_depth(scene, nan_depth, W, H, W * 4, NULL, 0, NULL),
                 PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_mesh(scene, &mesh), PLX_STATUS_INVALID_ARGUMENT);
    CHECK_MESSAGE(scene, "no valid");
    CHECK_STATUS(scene, plx_scene_surfaces(scene, &count, &surfaces), PLX_STATUS_OK);
    CHECK(count == 0 && surfaces == NULL);
    CHECK_STATUS(scene, plx_scene_clear_depth(scene), PLX_STATUS_OK);
    CHECK_STATUS(scene, plx_scene_mesh(scene, &mesh), PLX_STATUS_NOT_AVAILABLE);

    plx_scene_free(scene);
    plx_context_free(ctx);
    TEST_EXIT();
}
