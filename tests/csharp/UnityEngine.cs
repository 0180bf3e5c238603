// A stand-in for the few UnityEngine types ParallaxCompositor uses, so that tests/csharp.rs can
// compile and run the component under Mono. It mimics what matters here: Texture2D pixels are
// bottom-up (GetPixels32 starts with the bottom row), as in Unity. Not Unity's code.
using System;

namespace UnityEngine
{
    public class Object { }

    public class Component : Object { }

    public class Behaviour : Component { }

    public class MonoBehaviour : Behaviour { }

    public struct Vector2
    {
        public float x, y;
        public Vector2(float x, float y) { this.x = x; this.y = y; }
    }

    public struct Vector3
    {
        public float x, y, z;
        public Vector3(float x, float y, float z) { this.x = x; this.y = y; this.z = z; }
    }

    public struct Color32
    {
        public byte r, g, b, a;
        public Color32(byte r, byte g, byte b, byte a) { this.r = r; this.g = g; this.b = b; this.a = a; }
    }

    public enum TextureFormat { RGBA32 = 4 }

    public class Texture2D : Object
    {
        Color32[] pixels;
        public int width { get; private set; }
        public int height { get; private set; }
        public int applied;

        public Texture2D(int width, int height, TextureFormat format, bool mipChain)
        {
            this.width = width;
            this.height = height;
            pixels = new Color32[width * height];
        }

        /// <summary>Bottom row first, as Unity's.</summary>
        public Color32[] GetPixels32() { return (Color32[])pixels.Clone(); }

        public void SetPixels32(Color32[] colors)
        {
            if (colors.Length != pixels.Length)
                throw new ArgumentException("SetPixels32: wrong pixel count");
            pixels = (Color32[])colors.Clone();
        }

        public void Apply() { applied++; }
    }

    public static class Debug
    {
        public static int errors;
        public static void Log(object message) { Console.Error.WriteLine(message); }
        public static void LogWarning(object message) { Console.Error.WriteLine("warning: " + message); }
        public static void LogError(object message) { errors++; Console.Error.WriteLine("error: " + message); }
    }
}

namespace AOT
{
    /// <summary>Unity's marker for static methods called from native code (IL2CPP).</summary>
    [AttributeUsage(AttributeTargets.Method)]
    public class MonoPInvokeCallbackAttribute : Attribute
    {
        public MonoPInvokeCallbackAttribute(Type type) { }
    }
}
