//! Tests that cover every registered procedure: its scenario's parameter tables (defaults
//! shipped, ranges refused with the file and key, counts refused as fractions, the generated
//! `docs/parameters.md`), its assessment tree against its own measures.

use super::REGISTRY;
use super::document;
use crate::params::{Params, TOP_LEVEL, heading, table_key};
use crate::scenario::InputError;
use crate::sim::ProcedureInfo;

/// The TOML table `table` of a scenario (the root for the top level).
fn toml_table<'a>(root: &'a mut toml::Table, table: &str) -> &'a mut toml::Table {
    if table == TOP_LEVEL {
        return root;
    }
    root.get_mut(table)
        .and_then(toml::Value::as_table_mut)
        .unwrap_or_else(|| panic!("no [{table}]"))
}

/// The TOML value of a table key: `name` or an array element `name[i]`.
fn entry<'a>(table: &'a mut toml::Table, key: &str) -> &'a mut toml::Value {
    let (name, index) = match key.split_once('[') {
        Some((name, i)) => (name, i.trim_end_matches(']').parse::<usize>().ok()),
        None => (key, None),
    };
    let v = table
        .get_mut(name)
        .unwrap_or_else(|| panic!("no key {name}"));
    match index {
        Some(i) => v
            .as_array_mut()
            .and_then(|a| a.get_mut(i))
            .unwrap_or_else(|| panic!("no element {key}")),
        None => v,
    }
}

fn number(v: &toml::Value) -> Option<f64> {
    v.as_float().or_else(|| v.as_integer().map(|i| i as f64))
}

/// The procedure's scenario with `key` of `table` set to `value`, and what its reader
/// says of it.
fn plan_with(
    p: &ProcedureInfo,
    table: &str,
    key: &str,
    value: toml::Value,
) -> Result<(), InputError> {
    let mut root: toml::Table = toml::from_str(p.scenario).expect("the scenario is TOML");
    *entry(toml_table(&mut root, table), key) = value;
    let text = toml::to_string(&root).expect("writes back");
    (p.plan)("bad.toml", &text).map(|_| ())
}

/// One default per parameter: each shipped scenario holds every table's default, and
/// every number it holds has its table entry. The soft-body and grasper tables are the
/// exceptions: one table serves several models (kidney, vessels, block) or procedures, each
/// with its own values.
#[test]
fn shipped_scenarios_hold_the_table_defaults() {
    let soft = <crate::models::SoftBodyParams as Params>::SPECS;
    let grasper = <crate::scenario::Grasper as Params>::SPECS;
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
    let mut seen = Vec::new();
    for file in std::fs::read_dir(&dir).expect("assets/scenarios") {
        let path = file.expect("entry").path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let name = path.display().to_string();
        let text = std::fs::read_to_string(&path).expect("readable");
        let procedure = crate::scenario::procedure_of(&name, &text).expect("names one");
        let p = super::find(&procedure).expect("a registered procedure");
        assert_eq!(p.scenario, text, "{name} is {procedure}'s builtin scenario");
        (p.plan)(&name, &text).expect("the shipped scenario is valid");
        seen.push(p.name);
        let mut root: toml::Table = toml::from_str(&text).expect("TOML");
        for (table, specs) in p.param_tables {
            let t = toml_table(&mut root, table);
            for s in *specs {
                let v = number(entry(t, s.key)).expect("a number");
                let at = format!("{name}: {}", table_key(table, s.key));
                if *specs != soft && *specs != grasper {
                    assert_eq!(
                        v as f32, s.default as f32,
                        "{at}: the default is {}",
                        s.default
                    );
                }
            }
            // Every number the table holds is one of its specs.
            for (k, v) in t.iter() {
                let keys: Vec<String> = match v {
                    toml::Value::Array(a) if a.iter().all(|x| number(x).is_some()) => {
                        (0..a.len()).map(|i| format!("{k}[{i}]")).collect()
                    }
                    v if number(v).is_some() => vec![k.clone()],
                    _ => Vec::new(),
                };
                for key in keys {
                    assert!(
                        specs.iter().any(|s| s.key == key),
                        "{name}: {} has no table entry",
                        table_key(table, &key)
                    );
                }
            }
        }
    }
    let mut all: Vec<&str> = super::names().collect();
    all.sort_unstable();
    seen.sort_unstable();
    assert_eq!(seen, all, "one shipped scenario per registered procedure");
}

/// A value outside its range, in any table of any procedure, is refused with an error
/// naming the file, `table.key` and the range.
#[test]
fn out_of_range_values_name_file_and_table_key() {
    for p in REGISTRY {
        for (table, specs) in p.param_tables {
            for s in *specs {
                let mut bad = vec![s.max + s.max.abs() + 1.0];
                if !s.whole || s.min >= 1.0 {
                    bad.push(if s.whole {
                        s.min - 1.0
                    } else {
                        s.min - s.min.abs() - 1.0
                    });
                }
                // The bounds themselves are in range (as an f32 field reads them).
                for v in [s.min, s.max] {
                    let value = if s.whole {
                        toml::Value::Integer(v as i64)
                    } else {
                        toml::Value::Float(v)
                    };
                    let range = format!("between {} and {}", s.min, s.max);
                    if let Err(e) = plan_with(p, table, s.key, value) {
                        assert!(
                            !(e.key == table_key(table, s.key) && e.message.contains(&range)),
                            "{}: {v} is in range: {e}",
                            p.name
                        );
                    }
                }
                for v in bad {
                    let value = if s.whole {
                        toml::Value::Integer(v as i64)
                    } else {
                        toml::Value::Float(v)
                    };
                    let e = plan_with(p, table, s.key, value).expect_err("out of range");
                    assert_eq!(
                        (e.file.as_str(), e.key.as_str()),
                        ("bad.toml", table_key(table, s.key).as_str()),
                        "{}: {e}",
                        p.name
                    );
                    let range = format!("between {} and {}", s.min, s.max);
                    assert!(e.message.contains(&range), "{e}");
                }
            }
        }
    }
}

/// A count given a fraction is refused, and the message shows the line with the key.
#[test]
fn a_whole_number_given_a_fraction_is_refused() {
    let mut counted = 0;
    for p in REGISTRY {
        for (table, specs) in p.param_tables {
            for s in specs.iter().filter(|s| s.whole) {
                let e =
                    plan_with(p, table, s.key, toml::Value::Float(2.5)).expect_err("a fraction");
                let text = e.to_string();
                assert_eq!(e.file, "bad.toml");
                assert!(
                    text.contains(&format!("{} = 2.5", s.key)) && text.contains("u32"),
                    "{}: {text}",
                    p.name
                );
                counted += 1;
            }
        }
    }
    assert!(counted >= 5, "{counted}");
}

/// The generated document is in the repository and up to date.
#[test]
fn docs_parameters_md_is_current() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/parameters.md");
    let now = document(&super::CATALOG);
    if std::env::var_os("VESALIUS_BLESS").is_some() {
        std::fs::write(&path, &now).expect("docs/parameters.md written");
    }
    let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        on_disk == now,
        "docs/parameters.md is stale: VESALIUS_BLESS=1 cargo test --lib registry rewrites it"
    );
    for p in REGISTRY {
        for (table, specs) in p.param_tables {
            assert!(now.contains(&heading(table)));
            for s in *specs {
                assert!(now.contains(&format!("`{}`", s.key)));
            }
        }
    }
}

/// Every registered procedure's own tree reads, names it, and binds only measures it
/// reports; a tree naming a measure the procedure lacks is refused with the list.
#[test]
fn every_procedure_has_a_tree_that_binds_its_own_measures() {
    for info in REGISTRY {
        let file = format!("assets/assessment/{}.toml", info.name);
        let t = match crate::assess::load(&super::CATALOG, &file, info.assessment) {
            Ok(t) => t,
            Err(e) => panic!("{e}"),
        };
        assert_eq!(t.procedure, info.name);
        assert!(t.metrics().count() >= 3, "{}", info.name);
        assert!(t.top.len() >= 2, "{}", info.name);
    }
    let wrong = "procedure = \"sandbox\"\nversion = 1\ntitle = \"Skill\"\n\n[[node]]\n\
                 path = \"efficiency\"\nweight = 1\n\n[[node]]\npath = \"efficiency/time\"\n\
                 metric = \"t\"\nbetter = \"lower\"\nexpert = 10.0\nnovice = 50.0\n\
                 weight = 1\n";
    let e = crate::assess::load(&super::CATALOG, "wrong.toml", wrong)
        .expect_err("t is no sandbox measure");
    assert_eq!(e.key, "node (efficiency/time).metric");
    assert!(e.message.contains("max_probe_depth_m"), "{e}");
    let stranger = wrong.replace("procedure = \"sandbox\"", "procedure = \"appendix\"");
    assert_eq!(
        crate::assess::load(&super::CATALOG, "s.toml", &stranger)
            .expect_err("unknown")
            .key,
        "procedure"
    );
}

/// A rule's measure is checked against its procedure's: one the sandbox does not report is
/// refused, naming the rule.
#[test]
fn rules_bind_only_their_procedures_measures() {
    // The rules' measures are checked against the procedure's.
    let e = crate::assess::check_for(
        super::find("sandbox").expect("sandbox"),
        "rules.toml",
        &crate::assess::Tree::parse(
            "rules.toml",
            &format!(
                "{}\n[[rule]]\nid = \"x\"\nmetric = \"nope\"\nrises = true\nsay = \"y\"\n",
                super::find("sandbox").map_or("", |i| i.assessment)
            ),
        )
        .expect("parses"),
    )
    .expect_err("no such measure");
    assert_eq!(e.key, "rule (x).metric");
}

/// Each procedure's own reference cases (those that need its whole scene) pass, and every
/// case id is unique across the models', the procedures' and the known failures.
#[test]
fn every_procedures_own_cases_pass_with_unique_ids() {
    let mut seen = std::collections::HashSet::new();
    let all = crate::verify::cases_in(&super::CATALOG);
    for c in all.iter().chain(&crate::verify::known_failures()) {
        assert!(seen.insert(c.case), "duplicate case id {}", c.case);
    }
    let own: Vec<crate::sim::Case> = REGISTRY.iter().flat_map(|p| (p.options.cases)()).collect();
    assert!(own.len() >= 4, "{} cases of procedures", own.len());
    all_pass(&own);
}

/// Runs `cases`, each of which must pass.
fn all_pass(cases: &[crate::sim::Case]) {
    for r in crate::verify::run(cases) {
        assert!(
            r.passed,
            "{}/{}: reference {} measured {} error {} tolerance {}",
            r.model, r.case, r.reference, r.measured, r.rel_error, r.tolerance
        );
    }
}

/// The procedures' cases on the GPU compute path pass on the adapter there is (CI: lavapipe),
/// against the same references and tolerances as on the CPU, with ids unique among all.
#[test]
fn every_procedures_gpu_cases_pass_on_the_adapter_there_is() {
    let mut seen = std::collections::HashSet::new();
    let all = crate::verify::cases_in(&super::CATALOG);
    let gpu = crate::verify::gpu_cases_in(&super::CATALOG);
    for c in all.iter().chain(&gpu) {
        assert!(seen.insert(c.case), "duplicate case id {}", c.case);
    }
    let own: Vec<crate::sim::Case> = REGISTRY
        .iter()
        .flat_map(|p| (p.options.gpu_cases)())
        .collect();
    assert!(!own.is_empty(), "the rectum's");
    all_pass(&own);
}

/// Every procedure with a CPU preset has cases at its sizes (`verify --preset cpu`), and they
/// pass, with ids unique among all the cases.
#[test]
fn every_cpu_preset_has_cases_at_its_sizes_and_they_pass() {
    let mut seen = std::collections::HashSet::new();
    let all = crate::verify::cases_in(&super::CATALOG);
    let gpu = crate::verify::gpu_cases_in(&super::CATALOG);
    let preset = crate::verify::preset_cases_in(&super::CATALOG);
    for c in all.iter().chain(&gpu).chain(&preset) {
        assert!(seen.insert(c.case), "duplicate case id {}", c.case);
    }
    for p in REGISTRY.iter().filter(|p| p.options.cpu_preset.is_some()) {
        assert!(!(p.options.preset_cases)().is_empty(), "{}", p.name);
    }
    all_pass(&preset);
}

/// A preset lays its keys over the scenario and leaves the rest: the merged text is a valid
/// scenario of the procedure, smaller than its own, with every key the preset names and the
/// others as they were.
#[test]
fn every_cpu_preset_makes_a_smaller_valid_scenario() {
    let mut presets = 0;
    for p in REGISTRY {
        let Some(overlay) = p.options.cpu_preset else {
            continue;
        };
        presets += 1;
        let merged = crate::scenario::with_preset("builtin", p.scenario, "preset", overlay)
            .expect("the preset lays over the scenario");
        let (_, own) = super::CATALOG.plan("builtin", p.scenario).expect("own");
        let (_, coarse) = super::CATALOG.plan("preset", &merged).expect("valid");
        assert!(
            coarse.nodes < own.nodes,
            "{}: {} nodes",
            p.name,
            coarse.nodes
        );
        let (base, over, out): (toml::Table, toml::Table, toml::Table) = (
            toml::from_str(p.scenario).expect("toml"),
            toml::from_str(overlay).expect("toml"),
            toml::from_str(&merged).expect("toml"),
        );
        for (table, keys) in &base {
            let Some(keys) = keys.as_table() else {
                assert_eq!(out.get(table), Some(keys), "{}: {table}", p.name);
                continue;
            };
            for (key, value) in keys {
                let want = over.get(table).and_then(|t| t.get(key)).unwrap_or(value);
                assert_eq!(out[table].get(key), Some(want), "{}: {table}.{key}", p.name);
            }
        }
    }
    assert!(presets >= 1, "the rectum's");
}

#[test]
fn a_preset_that_is_not_toml_is_named_in_the_error() {
    let sandbox = super::find("sandbox").map_or("", |p| p.scenario);
    let e = crate::scenario::with_preset("builtin", sandbox, "my preset", "[anatomy\nrows = 1")
        .expect_err("not toml");
    assert_eq!(e.file, "my preset");
}
