"""A single-node SLURM cluster on this machine for the tests: munged with a fresh key,
slurmctld and slurmd in the foreground (-D, no systemd), a minimal slurm.conf, all in
a temporary folder, and jobcomp/filetxt as the scheduler's own record of every job.
Needs root (slurmd starts jobs as their users) and Debian's slurmctld, slurmd,
slurm-client and munge (./setup.sh installs them). Every failure to start says why,
with the daemon's log, and is raised as AssertionError: the test fails, never skips."""
import os
import re
import shutil
import signal
import socket
import subprocess
import tempfile
import time

DAEMONS = ("munged", "mungekey", "slurmctld", "slurmd", "sbatch", "scontrol", "sinfo")


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _tail(path, n=15):
    try:
        with open(path, errors="replace") as f:
            return "".join(f.readlines()[-n:])
    except OSError:
        return "(no log)"


class SlurmCluster:
    def __init__(self):
        self.dir = None
        self.procs = []  # (name, Popen, log path)

    # -- start ---------------------------------------------------------------
    def start(self):
        missing = [d for d in DAEMONS if not shutil.which(d, path=os.environ.get("PATH", "") + ":/usr/sbin:/sbin")]
        if missing:
            raise AssertionError(f"SLURM cannot run here: {', '.join(missing)} not installed; run ./setup.sh "
                                 "(apt-get install slurmctld slurmd slurm-client munge)")
        if os.geteuid() != 0:
            raise AssertionError("SLURM cannot run here: slurmd must run as root to start jobs, and this test "
                                 f"runs as uid {os.geteuid()}; run it as root (CI does)")
        self.dir = tempfile.mkdtemp(prefix="isohex_slurm_")
        os.chmod(self.dir, 0o700)
        for sub in ("munge", "state", "spool"):
            os.makedirs(os.path.join(self.dir, sub), mode=0o700)
        self.host = socket.gethostname().split(".")[0]
        self._start_munge()
        self.conf = self._write_conf()
        self.env = dict(os.environ, SLURM_CONF=self.conf)
        self._daemon("slurmctld", ["slurmctld", "-D", "-i", "-f", self.conf], self.path("slurmctld.log"))
        self._daemon("slurmd", ["slurmd", "-D", "-f", self.conf, "-N", self.host], self.path("slurmd.log"))
        self._wait_idle()

    def path(self, name):
        return os.path.join(self.dir, name)

    def _start_munge(self):
        key = self.path("munge/munge.key")
        subprocess.run(["mungekey", "--create", "--keyfile", key], check=True, capture_output=True)
        os.chmod(key, 0o400)
        self.munge_socket = self.path("munge/munge.socket")
        self._daemon("munged", ["munged", "--foreground", "--force", "--key-file", key, "--socket", self.munge_socket,
                                "--pid-file", self.path("munge/munged.pid"), "--seed-file", self.path("munge/seed"),
                                "--log-file", self.path("munged.log")], self.path("munged.log"))
        self._wait(lambda: os.path.exists(self.munge_socket), "munged", self.path("munged.log"), 20)

    def _write_conf(self):
        # the node as slurmd sees this machine (CPUs, sockets, RealMemory), addressed on loopback
        probe = subprocess.run(["slurmd", "-C"], capture_output=True, text=True)
        node = probe.stdout.splitlines()[0] if probe.returncode == 0 and probe.stdout else ""
        if not node.startswith("NodeName="):
            raise AssertionError(f"SLURM cannot run here: `slurmd -C` could not describe this machine: {probe.stderr}")
        node = re.sub(r"^NodeName=\S+", f"NodeName={self.host}", node)
        d = self.dir
        conf = f"""ClusterName=isohextest
SlurmctldHost={self.host}(127.0.0.1)
SlurmUser=root
SlurmdUser=root
SlurmctldPort={_free_port()}
SlurmdPort={_free_port()}
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket={self.munge_socket}
StateSaveLocation={d}/state
SlurmdSpoolDir={d}/spool
SlurmctldPidFile={d}/slurmctld.pid
SlurmdPidFile={d}/slurmd.pid
SlurmctldLogFile={d}/slurmctld.log
SlurmdLogFile={d}/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc={d}/jobcomp.txt
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
MpiDefault=none
SwitchType=switch/none
ReturnToService=2
MinJobAge=3600
SlurmdTimeout=60
{node} NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=cohort Nodes={self.host} Default=YES MaxTime=INFINITE State=UP
"""
        path = self.path("slurm.conf")
        with open(path, "w") as f:
            f.write(conf)
        return path

    def _daemon(self, name, cmd, log):
        with open(self.path(name + ".out"), "w") as out:
            proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
                                    env=dict(os.environ, SLURM_CONF=getattr(self, "conf", "")))
        self.procs.append((name, proc, log))
        time.sleep(0.5)
        if proc.poll() is not None:
            raise AssertionError(f"SLURM cannot run here: {name} exited with status {proc.returncode} at start:\n"
                                 f"{_tail(self.path(name + '.out'))}{_tail(log)}")

    def _wait(self, ready, name, log, seconds):
        t0 = time.time()
        while time.time() - t0 < seconds:
            if ready():
                return
            for n, p, lg in self.procs:
                if p.poll() is not None:
                    raise AssertionError(f"SLURM cannot run here: {n} exited with status {p.returncode}:\n"
                                         f"{_tail(self.path(n + '.out'))}{_tail(lg)}")
            time.sleep(0.5)
        raise AssertionError(f"SLURM cannot run here: {name} not ready after {seconds} s:\n{_tail(log)}")

    def _wait_idle(self):
        def idle():
            p = subprocess.run(["sinfo", "-h", "-o", "%t"], capture_output=True, text=True, env=self.env)
            return p.returncode == 0 and p.stdout.strip() in ("idle", "mix", "alloc")
        self._wait(idle, "the node (sinfo)", self.path("slurmd.log"), 60)

    # -- the scheduler's records ---------------------------------------------
    def scontrol(self, *args):
        p = subprocess.run(["scontrol", *args], capture_output=True, text=True, env=self.env)
        if p.returncode != 0:
            raise AssertionError(f"scontrol {' '.join(args)}: {p.stderr}")
        return p.stdout

    def job(self, jobid):
        """scontrol show job, as a dict of its KEY=VALUE fields."""
        return dict(re.findall(r"(\w+)=(\S*)", self.scontrol("show", "job", str(jobid))))

    def completed_jobs(self):
        """jobcomp/filetxt: one dict per finished job."""
        try:
            with open(self.path("jobcomp.txt")) as f:
                return [dict(re.findall(r"(\w+)=(\S*)", line)) for line in f if line.strip()]
        except FileNotFoundError:
            return []

    # -- stop ----------------------------------------------------------------
    def stop(self):
        for name, proc, _ in reversed(self.procs):
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
                try:
                    proc.wait(timeout=15)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        self.procs = []
        if self.dir and not os.environ.get("ISOHEX_KEEP_SLURM_DIR"):
            shutil.rmtree(self.dir, ignore_errors=True)
