"""Job execution.  The embedded runner (a process pool inside the service) is the default;
it needs no server.  Scale-out to several machines will hand the same job functions to a
real queue (see the later scale-out issue) instead of this pool."""
