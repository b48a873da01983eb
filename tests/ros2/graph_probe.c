/* What a ROS 2 tool sees of a running city, read with Cyclone DDS's C API only (no code of the
 * project): the participants and endpoints of DDS's builtin discovery topics with their USER_DATA
 * (rmw_cyclonedds reads `enclave=` and `typehash=` there), and the `ros_discovery_info` graph
 * (rmw_dds_common/msg/ParticipantEntitiesInfo, Jazzy's layout) decoded with C types that idlc
 * made from the IDL *derived from Debian's rosidl* for upstream's .msg
 * (tests/ros2/check_interfaces.py writes it), not from the project's IDL.
 *
 * Usage: graph_probe PARTITION SECONDS
 * Prints JSON lines on stdout: {"probe": GUID} first, then every ros_discovery_info sample as it
 * arrives ({"graph": ...}), then after SECONDS the alive participants ({"participant": ...}) and
 * readers and writers ({"endpoint": ...}) of the domain. tests/ros2/check_graph.py judges them. */
#include <dds/dds.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rmw_dds_common/msg/ParticipantEntitiesInfo.h"

static void print_guid(const unsigned char* v) {
  putchar('"');
  for (int i = 0; i < 16; i++) printf("%02x", v[i]);
  putchar('"');
}

static void print_string(const char* s, size_t n) {
  putchar('"');
  for (size_t i = 0; i < n; i++) {
    const unsigned char c = (unsigned char)s[i];
    if (c == '"' || c == '\\') {
      printf("\\%c", c);
    } else if (c < 0x20 || c >= 0x7f) {
      printf("\\u%04x", c);
    } else {
      putchar(c);
    }
  }
  putchar('"');
}

static void print_user_data(const dds_qos_t* qos) {
  void* value = NULL;
  size_t size = 0;
  if (qos != NULL && dds_qget_userdata(qos, &value, &size) && value != NULL) {
    print_string(value, size);
    dds_free(value);
  } else {
    printf("null");
  }
}

static void print_gids(const rmw_dds_common_msg_dds__Gid_* gids, uint32_t n) {
  putchar('[');
  for (uint32_t i = 0; i < n; i++) {
    if (i > 0) putchar(',');
    print_guid(gids[i].data);
  }
  putchar(']');
}

static void print_graph(const rmw_dds_common_msg_dds__ParticipantEntitiesInfo_* info) {
  printf("{\"graph\":{\"gid\":");
  print_guid(info->gid.data);
  printf(",\"nodes\":[");
  for (uint32_t i = 0; i < info->node_entities_info_seq._length; i++) {
    const rmw_dds_common_msg_dds__NodeEntitiesInfo_* node =
        &info->node_entities_info_seq._buffer[i];
    if (i > 0) putchar(',');
    printf("{\"namespace\":");
    print_string(node->node_namespace, strlen(node->node_namespace));
    printf(",\"name\":");
    print_string(node->node_name, strlen(node->node_name));
    printf(",\"readers\":");
    print_gids(node->reader_gid_seq._buffer, node->reader_gid_seq._length);
    printf(",\"writers\":");
    print_gids(node->writer_gid_seq._buffer, node->writer_gid_seq._length);
    putchar('}');
  }
  printf("]}}\n");
}

/* Prints every alive sample of a builtin topic's reader. */
static void print_builtin(dds_entity_t reader, int participants, const char* kind) {
  enum { kMax = 8192 };
  static void* samples[kMax];
  static dds_sample_info_t infos[kMax];
  memset(samples, 0, sizeof samples);
  const dds_return_t n = dds_read_mask(reader, samples, infos, kMax, kMax, DDS_ANY_STATE);
  if (n < 0) {
    fprintf(stderr, "graph_probe: dds_read_mask: %s\n", dds_strretcode(n));
    exit(1);
  }
  for (dds_return_t i = 0; i < n; i++) {
    if (!infos[i].valid_data || infos[i].instance_state != DDS_IST_ALIVE) continue;
    if (participants) {
      const dds_builtintopic_participant_t* p = samples[i];
      printf("{\"participant\":{\"guid\":");
      print_guid(p->key.v);
      printf(",\"user_data\":");
      print_user_data(p->qos);
      printf("}}\n");
    } else {
      const dds_builtintopic_endpoint_t* e = samples[i];
      printf("{\"endpoint\":{\"kind\":\"%s\",\"guid\":", kind);
      print_guid(e->key.v);
      printf(",\"participant\":");
      print_guid(e->participant_key.v);
      printf(",\"topic\":");
      print_string(e->topic_name, strlen(e->topic_name));
      printf(",\"type\":");
      print_string(e->type_name, strlen(e->type_name));
      printf(",\"user_data\":");
      print_user_data(e->qos);
      printf(",\"partitions\":[");
      uint32_t np = 0;
      char** ps = NULL;
      if (dds_qget_partition(e->qos, &np, &ps)) {
        for (uint32_t k = 0; k < np; k++) {
          if (k > 0) putchar(',');
          print_string(ps[k], strlen(ps[k]));
          dds_free(ps[k]);
        }
        dds_free(ps);
      }
      printf("]}}\n");
    }
  }
  if (n > 0) dds_return_loan(reader, samples, n);
}

int main(int argc, char** argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s PARTITION SECONDS\n", argv[0]);
    return 2;
  }
  const char* partition = argv[1];
  const double seconds = atof(argv[2]);
  const dds_entity_t pp = dds_create_participant(DDS_DOMAIN_DEFAULT, NULL, NULL);
  if (pp < 0) {
    fprintf(stderr, "graph_probe: dds_create_participant: %s\n", dds_strretcode(pp));
    return 1;
  }
  dds_guid_t me;
  dds_get_guid(pp, &me);
  printf("{\"probe\":");
  print_guid(me.v);
  printf("}\n");
  const dds_entity_t participants =
      dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSPARTICIPANT, NULL, NULL);
  const dds_entity_t publications =
      dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, NULL, NULL);
  const dds_entity_t subscriptions =
      dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, NULL, NULL);

  /* As rmw_cyclonedds reads the graph: reliable, transient-local, keep all, no partition but
   * the city's (a test city runs in its own). */
  dds_qos_t* sq = dds_create_qos();
  dds_qset_partition1(sq, partition);
  const dds_entity_t sub = dds_create_subscriber(pp, sq, NULL);
  dds_delete_qos(sq);
  const dds_entity_t topic = dds_create_topic(
      pp, &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc, "ros_discovery_info", NULL, NULL);
  dds_qos_t* rq = dds_create_qos();
  dds_qset_reliability(rq, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_durability(rq, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(rq, DDS_HISTORY_KEEP_ALL, 0);
  const dds_entity_t reader = dds_create_reader(sub, topic, rq, NULL);
  dds_delete_qos(rq);
  if (participants < 0 || publications < 0 || subscriptions < 0 || sub < 0 || topic < 0 ||
      reader < 0) {
    fprintf(stderr, "graph_probe: could not create the readers\n");
    return 1;
  }
  const dds_entity_t waitset = dds_create_waitset(pp);
  const dds_entity_t condition = dds_create_readcondition(reader, DDS_ANY_STATE);
  dds_waitset_attach(waitset, condition, 0);
  const dds_time_t end = dds_time() + (dds_duration_t)(seconds * 1e9);
  for (;;) {
    void* samples[64] = {0};
    dds_sample_info_t infos[64];
    const dds_return_t n = dds_take(reader, samples, infos, 64, 64);
    for (dds_return_t i = 0; i < n; i++) {
      if (infos[i].valid_data) print_graph(samples[i]);
    }
    if (n > 0) dds_return_loan(reader, samples, n);
    if (dds_time() >= end) break;
    dds_waitset_wait_until(waitset, NULL, 0, end);
  }
  print_builtin(participants, 1, "participant");
  print_builtin(publications, 0, "writer");
  print_builtin(subscriptions, 0, "reader");
  fflush(stdout);
  dds_delete(pp);
  return 0;
}
