//! The nodes a pool runs cases on: this machine, or every node of the allocation of several
//! nodes that `nlstudy run` runs in (a `submit --whole --nodes N` job, or a job script of the
//! user's). On an allocation each case, and each worker, is started on a node with free cores
//! by the scheduler: a Slurm job step (`srun --exact -N1 -n1 -c T -w NODE`), or LSF's `blaunch
//! -z HOST`. Nothing of this program runs a remote shell.

use crate::run::cluster::scheduler::Scheduler;
use std::path::Path;
use std::process::Command;

/// A node of the pool: its name on the allocation (`None`: this machine, no step) and the cores
/// the pool may use on it.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    pub name: Option<String>,
    pub cores: usize,
    /// Whose allocation it is: how a process is started there.
    pub scheduler: Scheduler,
}

/// Memory a step asks on a scheduler that counts it, from the job's own request: without it,
/// a step would ask all of the job's memory on its node and the next step would wait for it.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Memory {
    PerCpu(u64),
    PerNode(u64),
}

/// The pool's nodes: the allocation's when this process runs inside a Slurm job of several
/// nodes, else this machine with `cores`. An allocation whose nodes cannot be read is said on
/// standard error and run on this machine: its first node still runs every case.
pub fn nodes(cores: usize) -> Vec<Node> {
    let env = |name: &str| std::env::var(name).ok();
    let here = || this_machine(cores);
    let read = if env("SLURM_JOB_ID").is_some() {
        if env("SLURM_JOB_NUM_NODES").is_none_or(|n| n == "1") {
            return here();
        }
        slurm_nodes(env("SLURM_JOB_NODELIST"), env("SLURM_JOB_CPUS_PER_NODE"))
    } else if let (Some(_), Some(hosts)) = (env("LSB_JOBID"), env("LSB_MCPU_HOSTS")) {
        lsf_nodes(&hosts)
    } else {
        return here();
    };
    match read {
        Ok(nodes) if nodes.len() > 1 => nodes,
        Ok(_) => here(),
        Err(why) => {
            log::info!("the allocation's nodes are unknown ({why}): every case runs on this node");
            here()
        }
    }
}

/// This machine as the pool's one node, with `cores`.
pub fn this_machine(cores: usize) -> Vec<Node> {
    vec![Node {
        name: None,
        cores,
        scheduler: Scheduler::Slurm,
    }]
}

/// The address workers on the allocation's other nodes reach this node at: the one the
/// scheduler's own daemons use (Slurm's `NodeAddr` of this node, `SLURMD_NODENAME`), resolved.
/// `None` on this machine alone, under LSF, or where it cannot be read (said on the log): the
/// workers then answer through their job steps' standard streams.
pub fn this_nodes_address(nodes: &[Node]) -> Option<std::net::IpAddr> {
    let slurm = nodes.len() > 1 && nodes.iter().all(|n| n.scheduler == Scheduler::Slurm);
    if !slurm {
        return None;
    }
    let found = std::env::var("SLURMD_NODENAME")
        .map_err(|_| "SLURMD_NODENAME is not set".to_string())
        .and_then(|name| {
            let shown =
                crate::run::cluster::scheduler::run("scontrol", &["show", "node", &name, "-o"])?;
            node_address(&shown).ok_or_else(|| format!("scontrol shows no NodeAddr of {name}"))
        })
        .and_then(|address| {
            use std::net::ToSocketAddrs;
            let resolved = (address.as_str(), 0).to_socket_addrs();
            let first = resolved.map_err(|e| format!("{address}: {e}"))?.next();
            first
                .map(|a| a.ip())
                .ok_or_else(|| format!("{address} resolves to no address"))
        });
    found
        .inspect_err(|why| {
            log::info!("this node's address is unknown ({why}): workers answer through their job steps' standard streams")
        })
        .ok()
}

/// `NodeAddr=…` of `scontrol show node NAME -o`.
fn node_address(shown: &str) -> Option<String> {
    let value = shown
        .split_whitespace()
        .find_map(|word| word.strip_prefix("NodeAddr="))?;
    (!value.is_empty()).then(|| value.to_string())
}

/// What `nodes` says of an allocation's nodes, for the run's first lines.
pub fn describe(nodes: &[Node]) -> String {
    let each: Vec<String> = nodes
        .iter()
        .map(|n| {
            format!(
                "{} ({} cores)",
                n.name.as_deref().unwrap_or("this node"),
                n.cores
            )
        })
        .collect();
    format!(
        "{} nodes of the allocation, a worker step on each node's cores (a job step of its own only for a case over ranks or writing VTK files): {}",
        nodes.len(),
        each.join(", ")
    )
}

fn slurm_nodes(list: Option<String>, cpus: Option<String>) -> Result<Vec<Node>, String> {
    let list = list.ok_or("SLURM_JOB_NODELIST is not set")?;
    let cpus = cpus_per_node(&cpus.ok_or("SLURM_JOB_CPUS_PER_NODE is not set")?)?;
    // Slurm's own expansion of its host list syntax (`node[1-3,7]`), not a copy of it.
    let hostnames = crate::run::cluster::scheduler::run("scontrol", &["show", "hostnames", &list]);
    let names: Vec<String> = hostnames?.split_whitespace().map(str::to_string).collect();
    if names.len() != cpus.len() {
        return Err(format!(
            "{} nodes in {list} but {} counts of CPUs",
            names.len(),
            cpus.len()
        ));
    }
    Ok(names
        .into_iter()
        .zip(cpus)
        .map(|(name, cores)| Node {
            name: Some(name),
            cores,
            scheduler: Scheduler::Slurm,
        })
        .collect())
}

/// LSF's `LSB_MCPU_HOSTS`, host and slot count by turns (`hostA 4 hostB 4`), as nodes.
fn lsf_nodes(hosts: &str) -> Result<Vec<Node>, String> {
    let words: Vec<&str> = hosts.split_whitespace().collect();
    let bad = || format!("LSB_MCPU_HOSTS={hosts:?} is not hosts and slot counts such as `a 4 b 4`");
    if words.is_empty() || words.len() % 2 == 1 {
        return Err(bad());
    }
    words
        .chunks(2)
        .map(|pair| match pair[1].parse::<usize>() {
            Ok(cores) if cores > 0 => Ok(Node {
                name: Some(pair[0].to_string()),
                cores,
                scheduler: Scheduler::Lsf,
            }),
            _ => Err(bad()),
        })
        .collect()
}

/// `SLURM_JOB_CPUS_PER_NODE` as one count per node: `2(x3),1` is 2, 2, 2, 1.
fn cpus_per_node(text: &str) -> Result<Vec<usize>, String> {
    let bad = || format!("SLURM_JOB_CPUS_PER_NODE={text:?} is not counts such as 2(x3),1");
    let mut counts = Vec::new();
    for part in text.split(',') {
        let (count, times) = match part.split_once("(x") {
            Some((count, rest)) => (count, rest.strip_suffix(')').ok_or_else(bad)?),
            None => (part, "1"),
        };
        let count: usize = count.parse().map_err(|_| bad())?;
        let times: usize = times.parse().map_err(|_| bad())?;
        if count == 0 {
            return Err(bad());
        }
        counts.extend(std::iter::repeat_n(count, times));
    }
    Ok(counts)
}

/// The job's memory request, as its environment gives it.
fn job_memory() -> Option<Memory> {
    let megabytes = |name: &str| std::env::var(name).ok()?.parse::<u64>().ok();
    megabytes("SLURM_MEM_PER_CPU")
        .map(Memory::PerCpu)
        .or_else(|| megabytes("SLURM_MEM_PER_NODE").map(Memory::PerNode))
}

impl Node {
    /// The command that runs `program` on `cores` cores of this node: itself on this machine,
    /// else through a job step (`step`).
    pub fn command(&self, cores: usize, program: &Path) -> Command {
        let step = self.step(cores);
        let Some((srun, words)) = step.split_first() else {
            return Command::new(program);
        };
        let mut command = Command::new(srun);
        command.args(words).arg(program);
        command
    }

    /// The words that start a process of `cores` cores on this node as a job step (empty on
    /// this machine): one task on exactly those cores, on this node.
    pub fn step(&self, cores: usize) -> Vec<String> {
        self.step_asking(cores, job_memory())
    }

    fn step_asking(&self, cores: usize, memory: Option<Memory>) -> Vec<String> {
        let Some(name) = &self.name else {
            return Vec::new();
        };
        if self.scheduler == Scheduler::Lsf {
            // LSF places the task on the host; the job's affinity keeps its cores.
            return vec!["blaunch".into(), "-z".into(), name.clone()];
        }
        let mut words = vec![
            "srun".to_string(),
            "--exact".into(),
            "--nodes=1".into(),
            "--ntasks=1".into(),
            format!("--cpus-per-task={cores}"),
            format!("--nodelist={name}"),
        ];
        words.extend(self.memory(cores, memory));
        words
    }

    fn memory(&self, cores: usize, job: Option<Memory>) -> Option<String> {
        match job? {
            Memory::PerCpu(mb) => Some(format!("--mem-per-cpu={mb}")),
            Memory::PerNode(mb) => Some(format!(
                "--mem={}",
                (mb * cores as u64 / self.cores.max(1) as u64).max(1)
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_nodes_address_is_read_off_scontrol() {
        let shown = "NodeName=nlnode1 Arch=x86_64 CoresPerSocket=1 NodeAddr=10.213.57.11 NodeHostName=nlnode1 Version=22.05.8";
        assert_eq!(node_address(shown).as_deref(), Some("10.213.57.11"));
        assert_eq!(node_address("NodeName=a NodeAddr= State=IDLE"), None);
        assert_eq!(node_address("NodeName=a"), None);
        assert_eq!(this_nodes_address(&this_machine(2)), None);
    }

    #[test]
    fn cpus_per_node_expands_slurms_repeats() {
        assert_eq!(cpus_per_node("2(x3),1"), Ok(vec![2, 2, 2, 1]));
        assert_eq!(cpus_per_node("16"), Ok(vec![16]));
        for bad in ["", "2(x", "x,1", "0", "2(x3"] {
            let said = cpus_per_node(bad).unwrap_err();
            assert!(said.contains("SLURM_JOB_CPUS_PER_NODE"), "{bad}: {said}");
        }
    }

    #[test]
    fn a_step_is_one_task_of_its_cores_on_its_node() {
        let node = Node {
            name: Some("n7".into()),
            cores: 4,
            scheduler: Scheduler::Slurm,
        };
        assert_eq!(
            node.step_asking(2, None),
            [
                "srun",
                "--exact",
                "--nodes=1",
                "--ntasks=1",
                "--cpus-per-task=2",
                "--nodelist=n7"
            ]
        );
        assert_eq!(
            node.memory(2, Some(Memory::PerNode(8000))),
            Some("--mem=4000".into())
        );
        assert_eq!(
            node.memory(2, Some(Memory::PerCpu(500))),
            Some("--mem-per-cpu=500".into())
        );
        let here = &this_machine(2)[0];
        assert!(here.step(1).is_empty());
        let lsf = lsf_nodes("hostA 4 hostB 2").unwrap();
        assert_eq!(lsf.iter().map(|n| n.cores).collect::<Vec<_>>(), [4, 2]);
        assert_eq!(lsf[1].step(2), ["blaunch", "-z", "hostB"]);
        for bad in ["", "hostA", "hostA x", "hostA 0"] {
            assert!(
                lsf_nodes(bad).unwrap_err().contains("LSB_MCPU_HOSTS"),
                "{bad}"
            );
        }
    }
}
