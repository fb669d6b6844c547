/* Each command lives in src/cli/cmd_<name>.c and defines rths_cmd_<name>(argc, argv), where argv[0]
 * is the command name. main.c lists them; a command whose file is not linked is simply absent. */
#ifndef RTHS_CLI_COMMANDS_H
#define RTHS_CLI_COMMANDS_H

typedef int (*rths_command_fn)(int argc, char **argv);

int rths_cmd_model(int argc, char **argv) __attribute__((weak));
int rths_cmd_simulate(int argc, char **argv) __attribute__((weak));
int rths_cmd_fidelity(int argc, char **argv) __attribute__((weak));
int rths_cmd_frf(int argc, char **argv) __attribute__((weak));
int rths_cmd_chart(int argc, char **argv) __attribute__((weak));
int rths_cmd_tune(int argc, char **argv) __attribute__((weak));
int rths_cmd_controller(int argc, char **argv) __attribute__((weak));
int rths_cmd_view(int argc, char **argv) __attribute__((weak));
int rths_cmd_campaign(int argc, char **argv);

#endif
