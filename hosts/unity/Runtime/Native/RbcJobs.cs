// RbcJobs.cs -- the host's job system for a world's parallel work (ABI 1.10,
// rbc_world_def.enqueue_task / finish_task). A world given an IRbcJobSystem starts no
// threads of its own: each parallel phase of a step hands the job system a task of
// a few items and waits for it with Finish. The library's result is bitwise the one
// of its own pool at the same thread count, whoever runs the ranges.
using System;
using System.Collections.Generic;
using System.Runtime.InteropServices;
using System.Threading;

namespace RbCloth.Native
{
    /// <summary>One task of the library: run items [begin, end) with Run. Valid only
    /// until the Finish that waits for it returns. Never call the library from it.</summary>
    public struct RbcTask
    {
        readonly rbc_task_fn fn;
        readonly IntPtr context;

        internal RbcTask(rbc_task_fn fn, IntPtr context) { this.fn = fn; this.context = context; }

        public void Run(uint begin, uint end, uint worker) { fn(begin, end, worker, context); }

        // The task function is one of a few functions of the library: make a delegate
        // for each pointer once instead of once per phase.
        static readonly Dictionary<IntPtr, rbc_task_fn> s_delegates = new Dictionary<IntPtr, rbc_task_fn>();

        internal static rbc_task_fn DelegateFor(IntPtr ptr)
        {
            lock (s_delegates)
            {
                rbc_task_fn d;
                if (!s_delegates.TryGetValue(ptr, out d))
                {
                    d = (rbc_task_fn)Marshal.GetDelegateForFunctionPointer(ptr, typeof(rbc_task_fn));
                    s_delegates.Add(ptr, d);
                }
                return d;
            }
        }
    }

    /// <summary>A job system the world's steps run their parallel work on.</summary>
    public interface IRbcJobSystem
    {
        /// <summary>Run task over items [0, itemCount) in ranges of at least minRange
        /// items, on any threads, at once or later. Return an object for Finish, or
        /// null when every range has already run.</summary>
        object Enqueue(RbcTask task, uint itemCount, uint minRange);
        /// <summary>Return when every range of the task behind handle has returned.</summary>
        void Finish(object handle);
    }

    /// <summary>Every range at once on the calling thread, inside Enqueue: the serial
    /// executor the header allows (Enqueue returns null).</summary>
    public sealed class RbcInlineJobs : IRbcJobSystem
    {
        int enqueued;

        /// <summary>Tasks enqueued so far.</summary>
        public int EnqueuedTasks { get { return Volatile.Read(ref enqueued); } }

        public object Enqueue(RbcTask task, uint itemCount, uint minRange)
        {
            Interlocked.Increment(ref enqueued);
            if (itemCount > 0) task.Run(0, itemCount, 0);
            return null;
        }

        public void Finish(object handle) { }
    }

    /// <summary>Each range a work item of .NET's ThreadPool. `workers` is the world's
    /// thread_count - 1 (the stepping thread is worker 0): ranges are numbered 1 ..
    /// workers as the header asks (below thread_count).</summary>
    public sealed class RbcThreadPoolJobs : IRbcJobSystem
    {
        readonly uint workers;
        int enqueued, ranges;

        public RbcThreadPoolJobs(uint workers) { this.workers = Math.Max(1u, workers); }

        /// <summary>Tasks enqueued and ranges run so far (what a test checks to know
        /// the job system was used at all).</summary>
        public int EnqueuedTasks { get { return Volatile.Read(ref enqueued); } }
        public int RangesRun { get { return Volatile.Read(ref ranges); } }

        sealed class Job
        {
            public RbcTask Task;
            public int Pending;
            public readonly ManualResetEventSlim Done = new ManualResetEventSlim(false);
            public Exception Error;
        }

        sealed class Range
        {
            public Job Job;
            public uint Begin, End, Worker;
            public RbcThreadPoolJobs Owner;
        }

        static readonly WaitCallback s_run = RunRange;

        static void RunRange(object state)
        {
            var r = (Range)state;
            try { r.Job.Task.Run(r.Begin, r.End, r.Worker); }
            catch (Exception e) { r.Job.Error = e; } // must not unwind into the pool
            Interlocked.Increment(ref r.Owner.ranges);
            if (Interlocked.Decrement(ref r.Job.Pending) == 0) r.Job.Done.Set();
        }

        public object Enqueue(RbcTask task, uint itemCount, uint minRange)
        {
            Interlocked.Increment(ref enqueued);
            if (itemCount == 0) return null;
            uint size = Math.Max(1u, minRange);
            uint count = (itemCount + size - 1) / size;
            var job = new Job { Task = task, Pending = (int)count };
            for (uint k = 0; k < count; ++k)
            {
                uint begin = k * size, end = Math.Min(itemCount, begin + size);
                ThreadPool.QueueUserWorkItem(s_run, new Range
                {
                    Job = job, Begin = begin, End = end, Worker = 1 + k % workers, Owner = this
                });
            }
            return job;
        }

        public void Finish(object handle)
        {
            var job = (Job)handle;
            job.Done.Wait();
            job.Done.Dispose();
        }
    }
}
