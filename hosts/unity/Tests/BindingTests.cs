// BindingTests.cs -- runs the mono_binding checks (Mono/BindingTest.cs) in Unity's Test
// Runner (edit mode), against the library in the package's Plugins folder. The layout
// check needs the C compiler's offsets and runs only in the repository's `make test`.
// Not compiled here: this repository has no Unity (README.md).
using NUnit.Framework;

namespace RbCloth.Tests
{
    public class BindingTests
    {
        [Test]
        public void BindingChecksHold()
        {
            int rc = BindingTest.Run(null);
            if (rc == 77) Assert.Ignore("the library lacks the ABI 1.10 entry points");
            Assert.AreEqual(0, rc, "mono_binding checks failed (see the console)");
        }
    }
}
