/* dds_security_probe: what DDS Security lets one identity do, asked of Cyclone DDS's C API and
 * nothing else (no AutoDRIVE code: the answer is Cyclone's own).
 *
 *   dds_security_probe --keystore DIR --enclave NAME [--partition P] TOPIC...
 *
 * Joins the domain (ROS_DOMAIN_ID, else Cyclone's default) with a participant secured by the
 * enclave NAME of the sros2-style keystore DIR (scripts/autodrive-keystore makes one), the
 * plugins and the enclave's files given through the participant's dds.sec.* QoS properties as
 * common/dds/security.cpp gives them. Then, for each TOPIC (a DDS name such as
 * rt/autodrive/scm/heartbeat), it tries dds_create_topic, and with that topic dds_create_writer
 * and dds_create_reader (on a publisher and a subscriber of partition P, default
 * "security_probe"), deletes what it made, and prints one line:
 *
 *   probe TOPIC topic=RC writer=RC reader=RC
 *
 * RC is 0 when the entity was made, else Cyclone's negative return code (-13 is
 * DDS_RETCODE_NOT_ALLOWED_BY_SECURITY); writer and reader are '-' when the topic was refused.
 * The type is std_msgs/Int32 for every topic: permissions name topics, not types.
 *
 * First line "joined NAME"; exit 0 once every topic is probed, 1 when the participant cannot be
 * made (Cyclone's log on stderr says why), 2 on a usage error.
 * See docs/security.md ("Tested"). Used by tests/dds_security_roles_test.cpp. */
#define _GNU_SOURCE
#include <dds/dds.h>
#include <dlfcn.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "std_msgs/msg/Int32.h"

static const char* const kPlugins[3] = {"libdds_security_auth.so", "libdds_security_ac.so",
                                        "libdds_security_crypto.so"};

static int usage(const char* why) {
  fprintf(stderr,
          "dds_security_probe: %s\n"
          "usage: dds_security_probe --keystore DIR --enclave NAME [--partition P] TOPIC...\n",
          why);
  return 2;
}

/* Whether DIR holds the three security plugins. */
static int has_plugins(const char* dir) {
  char path[PATH_MAX];
  for (int i = 0; i < 3; ++i) {
    if (snprintf(path, sizeof path, "%s/%s", dir, kPlugins[i]) >= (int)sizeof path) return 0;
    if (access(path, R_OK) != 0) return 0;
  }
  return 1;
}

/* The plugins' directory, as SecurityPluginDirectory() finds it: AUTODRIVE_DDS_SECURITY_PLUGINS,
 * else libddsc0debian/ beside the libddsc this process runs with (Debian), else its directory. */
static int find_plugins(char* out, size_t size) {
  const char* env = getenv("AUTODRIVE_DDS_SECURITY_PLUGINS");
  if (env != NULL && *env != '\0') {
    return snprintf(out, size, "%s", env) < (int)size && has_plugins(out);
  }
  Dl_info info;
  char lib[PATH_MAX];
  if (dladdr((void*)&dds_create_participant, &info) == 0 || info.dli_fname == NULL ||
      realpath(info.dli_fname, lib) == NULL) {
    return 0;
  }
  char* slash = strrchr(lib, '/');
  if (slash == NULL) return 0;
  *slash = '\0';
  if (snprintf(out, size, "%s/libddsc0debian", lib) < (int)size && has_plugins(out)) return 1;
  return snprintf(out, size, "%s", lib) < (int)size && has_plugins(out);
}

/* Sets NAME to DIR/FILE (or "file:DIR/FILE" when URI); both are shorter than PATH_MAX. */
static void set_prop(dds_qos_t* qos, const char* name, const char* dir, const char* file, int uri) {
  char value[2 * PATH_MAX + 8];
  if (snprintf(value, sizeof value, "%s%s/%s", uri ? "file:" : "", dir, file) < (int)sizeof value) {
    dds_qset_prop(qos, name, value);
  }
}

static int created(dds_entity_t entity) { return entity > 0 ? 0 : (int)entity; }

int main(int argc, char** argv) {
  const char* keystore = NULL;
  const char* enclave = NULL;
  const char* partition = "security_probe";
  int first_topic = argc;
  for (int i = 1; i < argc; ++i) {
    if (strcmp(argv[i], "--keystore") == 0 && i + 1 < argc) {
      keystore = argv[++i];
    } else if (strcmp(argv[i], "--enclave") == 0 && i + 1 < argc) {
      enclave = argv[++i];
    } else if (strcmp(argv[i], "--partition") == 0 && i + 1 < argc) {
      partition = argv[++i];
    } else if (argv[i][0] == '-') {
      return usage("unknown option or missing value");
    } else {
      first_topic = i;
      break;
    }
  }
  if (keystore == NULL || enclave == NULL) return usage("--keystore and --enclave are required");
  if (enclave[0] != '/' || strstr(enclave, "..") != NULL) {
    return usage("the enclave must be an absolute ROS name such as /autodrive/scm");
  }
  if (first_topic >= argc) return usage("no topic to probe");

  char root[PATH_MAX];
  if (realpath(keystore, root) == NULL) return usage("the keystore does not exist");
  char dir[PATH_MAX];
  if (snprintf(dir, sizeof dir, "%s/enclaves%s", root, enclave) >= (int)sizeof dir) {
    return usage("the enclave's path is too long");
  }
  char plugins[PATH_MAX];
  if (!find_plugins(plugins, sizeof plugins)) {
    fprintf(stderr, "dds_security_probe: Cyclone DDS's security plugins not found\n");
    return 1;
  }

  dds_domainid_t domain = DDS_DOMAIN_DEFAULT;
  const char* domain_env = getenv("ROS_DOMAIN_ID");
  if (domain_env != NULL && *domain_env != '\0') {
    char* end = NULL;
    const unsigned long id = strtoul(domain_env, &end, 10);
    if (*end != '\0' || id > 232) return usage("ROS_DOMAIN_ID must be an integer in [0, 232]");
    domain = (dds_domainid_t)id;
  }

  dds_qos_t* qos = dds_create_qos();
  set_prop(qos, "dds.sec.auth.library.path", plugins, kPlugins[0], 0);
  dds_qset_prop(qos, "dds.sec.auth.library.init", "init_authentication");
  dds_qset_prop(qos, "dds.sec.auth.library.finalize", "finalize_authentication");
  set_prop(qos, "dds.sec.access.library.path", plugins, kPlugins[1], 0);
  dds_qset_prop(qos, "dds.sec.access.library.init", "init_access_control");
  dds_qset_prop(qos, "dds.sec.access.library.finalize", "finalize_access_control");
  set_prop(qos, "dds.sec.crypto.library.path", plugins, kPlugins[2], 0);
  dds_qset_prop(qos, "dds.sec.crypto.library.init", "init_crypto");
  dds_qset_prop(qos, "dds.sec.crypto.library.finalize", "finalize_crypto");
  set_prop(qos, "dds.sec.auth.identity_ca", dir, "identity_ca.cert.pem", 1);
  set_prop(qos, "dds.sec.auth.identity_certificate", dir, "cert.pem", 1);
  set_prop(qos, "dds.sec.auth.private_key", dir, "key.pem", 1);
  set_prop(qos, "dds.sec.access.permissions_ca", dir, "permissions_ca.cert.pem", 1);
  set_prop(qos, "dds.sec.access.governance", dir, "governance.p7s", 1);
  set_prop(qos, "dds.sec.access.permissions", dir, "permissions.p7s", 1);
  const dds_entity_t participant = dds_create_participant(domain, qos, NULL);
  dds_delete_qos(qos);
  if (participant < 0) {
    fprintf(stderr, "dds_security_probe: dds_create_participant as %s: %s (%d)\n", enclave,
            dds_strretcode(participant), (int)participant);
    return 1;
  }

  dds_qos_t* group = dds_create_qos();
  dds_qset_partition1(group, partition);
  const dds_entity_t publisher = dds_create_publisher(participant, group, NULL);
  const dds_entity_t subscriber = dds_create_subscriber(participant, group, NULL);
  dds_delete_qos(group);
  if (publisher < 0 || subscriber < 0) {
    fprintf(stderr, "dds_security_probe: cannot make a publisher and a subscriber\n");
    dds_delete(participant);
    return 1;
  }
  printf("joined %s\n", enclave);
  fflush(stdout);

  for (int i = first_topic; i < argc; ++i) {
    const dds_entity_t topic =
        dds_create_topic(participant, &std_msgs_msg_dds__Int32__desc, argv[i], NULL, NULL);
    if (topic < 0) {
      printf("probe %s topic=%d writer=- reader=-\n", argv[i], (int)topic);
    } else {
      const dds_entity_t writer = dds_create_writer(publisher, topic, NULL, NULL);
      const dds_entity_t reader = dds_create_reader(subscriber, topic, NULL, NULL);
      printf("probe %s topic=0 writer=%d reader=%d\n", argv[i], created(writer), created(reader));
      if (writer > 0) dds_delete(writer);
      if (reader > 0) dds_delete(reader);
      dds_delete(topic);
    }
    fflush(stdout);
  }
  dds_delete(participant);
  return 0;
}
