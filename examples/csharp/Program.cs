// A C# host of Parallax (bindings/csharp): loads a stereo pair, reconstructs it, stands a glTF
// model on the scene at a chosen pixel, renders the composite, and checks that failures arrive
// as ParallaxException with their status. Prints key=value lines and writes raw images (read by
// tests/csharp.rs, which also compares the struct layouts printed here with the Rust ones).
//
//   mono parallax_example.exe LEFT.png RIGHT.png MODEL.glb FOCAL_PX BASELINE_M X Y OUT_DIR
//
// OUT_DIR receives composite.rgba and photo.rgba (RGBA8, rows top first) and mask.f32 (coverage).
using System;
using System.Globalization;
using System.IO;
using System.Runtime.InteropServices;
using Parallax;

static class Program
{
    static readonly CultureInfo C = CultureInfo.InvariantCulture;

    static void Print(string key, object value)
    {
        string text = value is IFormattable ? ((IFormattable)value).ToString(null, C) : value.ToString();
        Console.WriteLine(key + "=" + text);
    }

    static string Vec(float[] v, int start, int n)
    {
        string[] parts = new string[n];
        for (int i = 0; i < n; i++)
            parts[i] = v[start + i].ToString("R", C);
        return string.Join(",", parts);
    }

    static int Main(string[] args)
    {
        if (args.Length != 8)
        {
            Console.Error.WriteLine("usage: parallax_example LEFT RIGHT MODEL.glb FOCAL_PX BASELINE_M X Y OUT_DIR");
            return 2;
        }
        // The marshalled size of every struct, for the layout check against the Rust types.
        foreach (Type t in typeof(PlxLight).Assembly.GetTypes())
            if (t.IsValueType && !t.IsEnum && t.Name.StartsWith("Plx") && t.IsLayoutSequential)
                Print("layout." + t.Name, Marshal.SizeOf(t));
        Print("version", Library.Version);
        Print("status_str_io", Library.StatusString(PlxStatus.Io));

        int warnings = 0;
        Library.SetLogCallback((level, message) => { if (level == PlxLogLevel.Warn) warnings++; }, PlxLogLevel.Warn);
        try
        {
            using (Context context = new Context())
            using (Scene scene = new Scene(context))
            {
                scene.LoadStereoPair(args[0], args[1]);
                double focal = double.Parse(args[3], C), baseline = double.Parse(args[4], C);
                scene.SetCalibration(focal, baseline);
                int w, h;
                scene.PhotoSize(out w, out h);
                Print("size", w + "x" + h);
                Print("disparity_centre_px", scene.Disparity()[w / 2, h / 2]);
                Print("depth_centre_m", scene.Depth()[w / 2, h / 2]);
                Print("mesh_triangles", scene.Mesh().TriangleCount);
                Print("surfaces", scene.Surfaces().Length);

                int stages = 0;
                scene.SetProgressCallback((stage, fraction) => { if (fraction == 1) stages++; return true; });

                float x = float.Parse(args[5], C), y = float.Parse(args[6], C);
                PlxHit hit = scene.Pick(x, y);
                Print("hit", hit.Hit);
                Print("point", Vec(hit.Point, 0, 3));
                Print("normal", Vec(hit.Normal, 0, 3));
                Print("up", Vec(scene.Up(), 0, 3));
                uint id = scene.AddArtefactPath(args[2]);
                float[] m = scene.PlaceArtefact(id, x, y, 0.3f, 30);
                Print("artefact_transform", Vec(m, 0, 16));
                Bounds b = scene.ArtefactBounds(id);
                Print("artefact_world_min", Vec(b.WorldMin, 0, 3));
                Print("artefact_world_max", Vec(b.WorldMax, 0, 3));
                Print("artefact_warnings", scene.ArtefactWarnings(id).Length);

                PlxLight[] lights = scene.Lights();
                Print("lights", lights.Length);
                MainLight main = scene.MainLight();
                Print("main_light_direction", Vec(main.Direction, 0, 3));
                Print("sh9_0", Vec(scene.Sh9(), 0, 3));

                // The composite, RGBA8 rows top first, and the artefacts' coverage.
                byte[] composite = new byte[w * h * 4];
                float[] mask = new float[w * h];
                scene.Render(composite, w, h, PlxPixelFormat.Rgba8, PlxRenderOptions.CreateDefault(), mask);
                Print("report_has_render", scene.Report().Contains("\"render\"") ? 1 : 0);
                File.WriteAllBytes(Path.Combine(args[7], "composite.rgba"), composite);
                byte[] maskBytes = new byte[mask.Length * 4];
                Buffer.BlockCopy(mask, 0, maskBytes, 0, maskBytes.Length);
                File.WriteAllBytes(Path.Combine(args[7], "mask.f32"), maskBytes);
                byte[] photo = new byte[w * h * 4];
                scene.Photo(photo, w, h, PlxPixelFormat.Rgba8);
                File.WriteAllBytes(Path.Combine(args[7], "photo.rgba"), photo);
                Print("progress_stages", stages);

                // Another composition of the same reconstruction: without the box it is the photo.
                using (Scene variant = scene.Clone())
                {
                    variant.RemoveArtefact(id);
                    byte[] plain = variant.Render();
                    bool same = plain.Length == photo.Length;
                    for (int i = 0; same && i < plain.Length; i++)
                        same = plain[i] == photo[i];
                    Print("clone_without_box_is_photo", same ? 1 : 0);
                }

                UnityRenderThread(scene, composite, w, h);

                // Host lights replace the estimate and come back as given.
                scene.SetLights(new PlxLight[] { PlxLight.Directional(new float[] { 0, -1, 0 }, 5, new float[] { 2, 2, 2 }) });
                PlxLight[] mine = scene.Lights();
                Print("host_lights", mine.Length + ":" + Vec(mine[0].Direction, 0, 3) + ":" + mine[0].Size.ToString("R", C));
                scene.ResetLights();

                EveryOtherCall(scene, args[2], x, y, w, h);

                // Failures arrive as ParallaxException with the status and the library's message.
                Expect("error_missing_file", () => scene.LoadStereoPair(Path.Combine(args[7], "missing.png"), args[1]));
                Expect("error_unknown_artefact", () => scene.RemoveArtefact(9999));
                Expect("error_bad_size", () => scene.Render(new byte[4], 1, 1, PlxPixelFormat.Rgba8));
                scene.SetProgressCallback((stage, fraction) => false);
                scene.SetStereoOptions(PlxStereoOptions.CreateDefault()); // new options: stereo reruns
                Expect("error_cancelled", () => scene.Disparity());
                scene.SetProgressCallback((stage, fraction) => { throw new InvalidOperationException("host bug"); });
                Expect("error_callback_threw", () => scene.Disparity());
                scene.SetProgressCallback(null);
                Print("disparity_after_cancel", scene.Disparity()[w / 2, h / 2]);
            }
            Expect("error_no_pair", () =>
            {
                using (Context c = new Context())
                using (Scene s = new Scene(c))
                    s.Render(new byte[4], 1, 1);
            });
        }
        catch (ParallaxException e)
        {
            Console.Error.WriteLine("parallax error " + e.Status + ": " + e.Message);
            return 1;
        }
        finally
        {
            Library.SetLogCallback(null);
        }
        Print("log_warnings", warnings);
        return 0;
    }

    // What Unity does with a library built with the `unity` feature: register a render target,
    // then call the render-event function on its render thread (here: another thread).
    static void UnityRenderThread(Scene scene, byte[] expected, int w, int h)
    {
        IntPtr function;
        try
        {
            function = UnityRenderEvents.Function;
        }
        catch (EntryPointNotFoundException)
        {
            Print("unity_plugin", "absent");
            return;
        }
        const int eventId = 7;
        byte[] target = new byte[w * h * 4];
        UnityRenderEvents.SetTarget(eventId, scene, target, w, h);
        PlxUnityRenderingEvent render = (PlxUnityRenderingEvent)Marshal.GetDelegateForFunctionPointer(function, typeof(PlxUnityRenderingEvent));
        System.Threading.Thread thread = new System.Threading.Thread(() => { render(eventId); render(eventId + 1); });
        thread.Start();
        thread.Join();
        UnityRenderEvents.RemoveTarget(eventId);
        ulong runs;
        PlxStatus status = UnityRenderEvents.LastStatus(eventId, out runs);
        Print("unity_event", status + ":" + runs);
        Print("unity_event_message", UnityRenderEvents.LastMessage(eventId));
        int maxDiff = 0;
        for (int i = 0; i < target.Length; i++)
            maxDiff = Math.Max(maxDiff, Math.Abs(target[i] - expected[i]));
        Print("unity_event_max_diff", maxDiff);
        status = UnityRenderEvents.LastStatus(eventId + 1, out runs);
        Print("unity_unregistered", status + ":" + runs + ":" + UnityRenderEvents.LastMessage(eventId + 1));
    }

    // The rest of the API through the wrapper, once each, so that every declaration's marshalling
    // runs: camera, clip, depth buffer, confidence, mesh and stereo options, placement, artefacts
    // from memory, flags, SH9, environment, host depth, the context's pixel cap.
    static void EveryOtherCall(Scene scene, string glb, float x, float y, int w, int h)
    {
        CameraInfo cam = scene.Camera();
        Print("camera", cam.Intrinsics.Fx.ToString("R", C) + "," + cam.Intrinsics.Cx.ToString("R", C) + "," + cam.Intrinsics.Cy.ToString("R", C));
        scene.SetClip(0.25f, 20);
        cam = scene.Camera();
        Print("clip", cam.Near.ToString("R", C) + "," + cam.Far.ToString("R", C));
        FloatGrid gl = scene.DepthBuffer(PlxDepthEncoding.OpenglWindow);
        float lo = float.MaxValue, hi = float.MinValue;
        foreach (float d in gl.Data) { lo = Math.Min(lo, d); hi = Math.Max(hi, d); }
        Print("depth_buffer_range", lo.ToString("R", C) + "," + hi.ToString("R", C));
        scene.SetClip(0, 0);
        FloatGrid confidence = scene.Confidence();
        Print("confidence_size", confidence.Width + "x" + confidence.Height);

        int full = scene.Mesh().TriangleCount;
        PlxMeshOptions mo = PlxMeshOptions.CreateDefault();
        mo.Step = 2;
        scene.SetMeshOptions(mo);
        int coarse = scene.Mesh().TriangleCount;
        scene.ResetMeshOptions();
        Print("mesh_step2_smaller", coarse < full && coarse > 0 ? 1 : 0);
        PlxStereoOptions so = PlxStereoOptions.CreateDefault();
        so.Preset = (uint)PlxStereoPreset.Fast;
        scene.SetStereoOptions(so);
        Print("fast_disparity_size", scene.Disparity().Width);
        scene.ResetStereoOptions();

        PlxHit hit = scene.Pick(x, y);
        float[] placed = scene.Place(x, y, 0.3f);
        Print("place_translation", Vec(placed, 12, 3));
        float[] onRay = scene.PlaceOnRay(new float[] { 0, 0, 0 }, hit.Point, 0.3f);
        Print("place_on_ray_translation", Vec(onRay, 12, 3));

        uint id = scene.AddArtefactMemory(File.ReadAllBytes(glb));
        float[] t = { 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0.5f, -0.25f, -2, 1 };
        scene.SetArtefactTransform(id, t);
        Bounds b = scene.ArtefactBounds(id);
        Print("memory_artefact_world_min", Vec(b.WorldMin, 0, 3));
        scene.SetArtefactFlags(id, false, false, false);
        scene.RemoveArtefact(id);

        float[] sh = new float[27];
        sh[0] = 0.25f; sh[1] = 0.5f; sh[2] = 0.75f;
        scene.SetSh9(sh);
        Print("sh9_set", Vec(scene.Sh9(), 0, 3));
        scene.SetSh9(null);
        byte[] env = new byte[16 * 8 * 3];
        for (int i = 0; i < env.Length; i++) env[i] = 128;
        scene.SetEnvironmentEquirect(env, 16, 8, PlxPixelFormat.Rgb8);
        int cube = scene.EnvironmentCubeSize();
        byte[] face = scene.EnvironmentCubeFace(2, PlxPixelFormat.RgbaF32);
        float[] texels = new float[face.Length / 4];
        Buffer.BlockCopy(face, 0, texels, 0, face.Length);
        Print("environment_cube", cube + ":" + (face.Length == cube * cube * 16 ? 1 : 0) + ":" + texels[0].ToString("R", C));
        scene.ResetEnvironment();

        // Host depth: a stereo pair of one grey and a wall 2 m away; no stereo runs.
        using (Context context = new Context())
        using (Scene host = new Scene(context))
        {
            byte[] grey = new byte[16 * 8 * 4];
            for (int i = 0; i < grey.Length; i++) grey[i] = 100;
            host.SetStereoPair(grey, grey, 16, 8, PlxPixelFormat.Bgra8);
            float[] depth = new float[16 * 8];
            for (int i = 0; i < depth.Length; i++) depth[i] = 2;
            PlxCamera camera;
            camera.Fx = camera.Fy = 20;
            camera.Cx = 8;
            camera.Cy = 4;
            host.SetDepth(depth, 16, 8, null, camera);
            Print("host_depth", host.Depth()[3, 3].ToString("R", C));
            Print("host_depth_stereo_skipped", host.Report().Contains("host depth given") ? 1 : 0);
            Print("host_camera_fx", host.Camera().Intrinsics.Fx.ToString("R", C));
            host.ClearDepth();
            PlxCalibration cal = new PlxCalibration();
            cal.FocalPx = 20;
            cal.BaselineM = 0.1;
            cal.Cx = 8;
            cal.Cy = 4;
            host.SetCalibration(cal);
        }
        // The context's pixel cap.
        using (Context small = new Context(1000, null))
        using (Scene capped = new Scene(small))
            Expect("error_pixel_cap", () => capped.SetStereoPair(new byte[w * h * 4], new byte[w * h * 4], w, h, PlxPixelFormat.Rgba8));
    }

    static void Expect(string key, Action action)
    {
        try
        {
            action();
            Print(key, "none");
        }
        catch (ParallaxException e)
        {
            Print(key, e.Status + ": " + e.Message.Replace('\n', ' '));
        }
    }
}
